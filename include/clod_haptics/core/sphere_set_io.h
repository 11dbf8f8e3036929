#pragma once

#include <iosfwd>
#include <string>

#include "clod_haptics/core/sphere_set.h"

namespace clod_haptics {

/**
 * \brief Writes a sphere set as YAML: mesh name, scale, clustering distance, build statistics and,
 * per sphere, its centre, radius and triangle indices. Doubles are written with 17 significant
 * digits so a read gives the same numbers back.
 * \throws FormatError when the file cannot be written.
 */
void writeSphereSetYaml(const ClodSphereSet& set, const std::string& path);
/** \brief The same, to a stream. */
void writeSphereSetYaml(const ClodSphereSet& set, std::ostream& out);

/**
 * \brief Reads what writeSphereSetYaml wrote (not general YAML).
 * \throws FormatError naming the line for anything unexpected.
 */
ClodSphereSet readSphereSetYaml(const std::string& path);

}  // namespace clod_haptics
