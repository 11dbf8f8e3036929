#pragma once

#include <visualization_msgs/MarkerArray.h>

#include <Eigen/Geometry>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "clod_haptics/core/detector.h"
#include "clod_haptics/core/mesh.h"
#include "clod_haptics/core/scene.h"

namespace clod_haptics {

/** \brief One object as the markers draw it. */
struct DisplayObject {
  std::string name;
  std::string frameId;                                       ///< RViz follows the frame, moving or not
  Eigen::Isometry3d offset = Eigen::Isometry3d::Identity();  ///< the mesh's pose in frameId
  std::string meshResource;                                  ///< package:// or file:// URI (scenes)
  double scale = 1.0;
  std::shared_ptr<const TriangleMesh> mesh;  ///< drawn as triangles for a single mesh
  bool drawn = true;
  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

/** \brief The last answered pose, copied by the pose thread for the display. */
struct DisplayFrame {
  std::uint64_t seq = 0;  ///< 0: no pose yet
  Vec3 pointer = Vec3::Zero();
  double radius = 0.0;
  Vec3 force = Vec3::Zero();  ///< N, scene frame
  bool haveProxy = false;  ///< force_model proxy: the proxy is drawn beside the pointer
  Vec3 proxy = Vec3::Zero();
  std::vector<SceneContact> contacts;
  std::vector<char> near;  ///< per object: the pointer reached its bound
  std::vector<Eigen::Isometry3d, Eigen::aligned_allocator<Eigen::Isometry3d>> poses;  ///< world-from-object
};

/** \brief Which markers to show (dynamic_reconfigure's show_* switches). */
struct DisplaySwitches {
  bool mesh = true, spheres = false, hitSpheres = false, contact = true, pointer = true;
};

/**
 * \brief The markers of a detector: the meshes, each object's level, the spheres the pointer hits, the
 * contacts and the pointer. update() appends only what changed since its last call (a new subscriber calls
 * invalidate() first), so a still scene costs nothing. A single mesh (singleMesh) is drawn as one
 * TRIANGLE_LIST in namespace "mesh", its spheres in "spheres" and "hit_spheres"; a scene draws each mesh by
 * reference (MESH_RESOURCE, namespace "scene_mesh", id = object) and suffixes the sphere namespaces with
 * "/<object name>". Contact markers carry the object's index as id. Display thread only.
 */
class DetectorDisplay {
 public:
  DetectorDisplay(std::string sceneFrame, std::vector<DisplayObject, Eigen::aligned_allocator<DisplayObject>> objects,
                  bool singleMesh);

  /** \brief Everything is sent again by the next update (a new subscriber). */
  void invalidate() { everything_ = true; }
  /** \brief New switches; what they change is sent by the next update. */
  void setSwitches(const DisplaySwitches& switches);
  /** \brief Appends to out the markers that changed; levels[i] is object i's level (may be null). */
  void update(const std::vector<std::shared_ptr<const ClodDetector>>& levels, const DisplayFrame& frame,
              visualization_msgs::MarkerArray& out);

 private:
  std::string ns(const char* base, std::size_t object) const;
  std_msgs::Header objectHeader(std::size_t object) const;
  void appendMesh(std::size_t object, visualization_msgs::MarkerArray& out) const;
  void appendLevel(std::size_t object, const ClodDetector* level, visualization_msgs::MarkerArray& out);
  void appendHits(std::size_t object, const ClodDetector* level, const DisplayFrame& frame,
                  visualization_msgs::MarkerArray& out);
  void appendContact(std::size_t object, const DisplayFrame& frame, visualization_msgs::MarkerArray& out);
  void appendPointer(const DisplayFrame& frame, visualization_msgs::MarkerArray& out) const;
  /** \brief Length of the normal arrow and of the force arrow per newton: a fraction of the model's size. */
  double arrowLength(double radius) const;

  std::string sceneFrame_;
  std::vector<DisplayObject, Eigen::aligned_allocator<DisplayObject>> objects_;
  bool singleMesh_;
  double modelSize_ = 0.0;  // largest bounds diagonal of the objects drawn as triangles (0: none)
  DisplaySwitches switches_;
  bool everything_ = true;
  bool meshSwitched_ = false, spheresSwitched_ = false;
  std::uint64_t shownSeq_ = 0;
  std::vector<std::uint64_t> shownLevelIds_;  // ClodDetector::id() drawn per object (an id is never reused)
  std::vector<std::size_t> shownSpheres_, shownHit_;
  std::vector<char> shownContact_;
  std::vector<std::uint32_t> hitBuffer_;
};

}  // namespace clod_haptics
