#pragma once

#include <string>

namespace clod_haptics {

/**
 * \brief Turns a mesh parameter into a file path: `package://pkg/rel` becomes `<path of pkg>/rel`
 * (ros::package::getPath); `file://` is stripped; an absolute path is returned as is (the loader
 * reports a missing file); a relative or `~/` path is resolved as the user typed it, against the
 * directory roslaunch was started from ($PWD), then the node's working directory (resolveUserPath,
 * core/user_path.h), and the absolute path found is returned.
 * \throws MeshLoadError when the URI is empty, its scheme is unknown, the package is not found, or a
 * relative path exists in none of the directories tried (the message names every path tried).
 */
std::string resolveMeshPath(const std::string& uri);

}  // namespace clod_haptics
