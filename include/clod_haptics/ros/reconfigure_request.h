#pragma once

#include <dynamic_reconfigure/Config.h>

#include <string>
#include <vector>

namespace clod_haptics {

/**
 * \brief The detector's dynamic_reconfigure request for `name value [name value ...]` (the `set` tool): each
 * name is a parameter of cfg/Detector.cfg or a short alias (distance: clustering_distance, radius:
 * pointer_radius, mode: detection_mode), typed by the generated description (bool: true/false/1/0).
 * \throws std::invalid_argument naming the problem: an odd count, an unknown name (the message lists the known
 * ones), a value that is not of the parameter's type or lies outside its range.
 */
dynamic_reconfigure::Config detectorReconfigureRequest(const std::vector<std::string>& args);

/** \brief The value of parameter name in config as text ("" when config does not hold it). */
std::string configValue(const dynamic_reconfigure::Config& config, const std::string& name);

}  // namespace clod_haptics
