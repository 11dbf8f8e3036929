#pragma once

#include <string>

namespace clod_haptics {

/**
 * \brief Turns a mesh parameter into a file path: a plain path is returned as is, `file://` is
 * stripped, `package://pkg/rel` becomes `<path of pkg>/rel` (ros::package::getPath).
 * \throws MeshLoadError when the URI is empty, its scheme is unknown or the package is not found.
 */
std::string resolveMeshPath(const std::string& uri);

}  // namespace clod_haptics
