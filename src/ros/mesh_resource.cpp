#include "clod_haptics/ros/mesh_resource.h"

#include <ros/package.h>

#include "clod_haptics/core/errors.h"

namespace clod_haptics {

std::string resolveMeshPath(const std::string& uri) {
  if (uri.empty()) throw MeshLoadError(uri, "the mesh parameter is empty");
  const std::string packageScheme = "package://";
  const std::string fileScheme = "file://";
  if (uri.compare(0, fileScheme.size(), fileScheme) == 0) return uri.substr(fileScheme.size());
  if (uri.compare(0, packageScheme.size(), packageScheme) == 0) {
    const std::string rest = uri.substr(packageScheme.size());
    const std::size_t slash = rest.find('/');
    const std::string package = rest.substr(0, slash);
    if (package.empty()) throw MeshLoadError(uri, "no package name after package://");
    const std::string root = ros::package::getPath(package);
    if (root.empty()) throw MeshLoadError(uri, "package '" + package + "' not found (is ROS_PACKAGE_PATH set?)");
    return slash == std::string::npos ? root : root + rest.substr(slash);
  }
  const std::size_t scheme = uri.find("://");
  if (scheme != std::string::npos && uri.find('/') > scheme) {
    throw MeshLoadError(uri,
                        "unsupported URI scheme '" + uri.substr(0, scheme) + "' (use a path, file:// or package://)");
  }
  return uri;
}

}  // namespace clod_haptics
