#include "clod_haptics/ros/mesh_resource.h"

#include <ros/package.h>

#include "clod_haptics/core/errors.h"
#include "clod_haptics/core/user_path.h"

namespace clod_haptics {

std::string resolveMeshPath(const std::string& uri) {
  if (uri.empty()) throw MeshLoadError(uri, "the mesh parameter is empty");
  const std::string packageScheme = "package://";
  const std::string fileScheme = "file://";
  std::string path = uri;
  if (uri.compare(0, fileScheme.size(), fileScheme) == 0) path = uri.substr(fileScheme.size());
  if (uri.compare(0, packageScheme.size(), packageScheme) == 0) {
    const std::string rest = uri.substr(packageScheme.size());
    const std::size_t slash = rest.find('/');
    const std::string package = rest.substr(0, slash);
    if (package.empty()) throw MeshLoadError(uri, "no package name after package://");
    const std::string root = ros::package::getPath(package);
    if (root.empty()) throw MeshLoadError(uri, "package '" + package + "' not found (is ROS_PACKAGE_PATH set?)");
    return slash == std::string::npos ? root : root + rest.substr(slash);
  }
  const std::size_t scheme = path.find("://");
  if (scheme != std::string::npos && path.find('/') > scheme) {
    throw MeshLoadError(uri,
                        "unsupported URI scheme '" + path.substr(0, scheme) + "' (use a path, file:// or package://)");
  }
  if (path.empty()) throw MeshLoadError(uri, "no path after file://");
  if (path.front() == '/') return path;  // the loader names a missing absolute path itself
  const UserPathResolution resolved = resolveUserPath(path);
  if (!resolved.found()) throw MeshLoadError(uri, "not found: tried " + resolved.triedText());
  return resolved.path;
}

}  // namespace clod_haptics
