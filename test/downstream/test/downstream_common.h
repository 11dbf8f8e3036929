// What both downstream tests share: the installed package's share folder and its bundled mesh.
#pragma once

#include <gtest/gtest.h>
#include <ros/package.h>

#include <clod_haptics/core/mesh_loader.h>

#include <cstdlib>
#include <memory>
#include <string>

namespace downstream {

/** \brief clod_haptics' share folder, checked to be the one under $CLOD_INSTALL_PREFIX (the install space). */
inline std::string installedShare() {
  const std::string share = ros::package::getPath("clod_haptics");
  const char* prefix = std::getenv("CLOD_INSTALL_PREFIX");
  EXPECT_TRUE(prefix != nullptr) << "CLOD_INSTALL_PREFIX is not set";
  if (prefix != nullptr) {
    EXPECT_EQ(share, std::string(prefix) + "/share/clod_haptics");
  }
  return share;
}

/** \brief The bundled torus from the install space, normalised to the unit cube (as the service loads it). */
inline std::shared_ptr<const clod_haptics::TriangleMesh> installedTorus() {
  clod_haptics::MeshLoadOptions options;
  options.normalize = true;
  return std::make_shared<const clod_haptics::TriangleMesh>(
      clod_haptics::loadMesh(installedShare() + "/data/meshes/torus.obj", options));
}

}  // namespace downstream
