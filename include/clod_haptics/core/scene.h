#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "clod_haptics/core/contact.h"
#include "clod_haptics/core/detector.h"
#include "clod_haptics/core/mesh.h"

namespace clod_haptics {

/** \brief One object's answer to a scene query. */
struct SceneContact {
  std::uint32_t object = 0;  ///< index of the object in the scene
  ContactResult local;       ///< the object's own answer, in its mesh frame
  Vec3 point = Vec3::Zero();   ///< local.point in the world frame
  Vec3 normal = Vec3::Zero();  ///< local.normal in the world frame (unit, outward)
};

/** \brief The combined answer of a scene query: what a penalty force needs, plus statistics. */
struct SceneQueryResult {
  bool contact = false;                ///< at least one object touched
  std::uint32_t contacts = 0;          ///< entries written to the caller's array (at most its capacity)
  std::uint32_t touched = 0;           ///< objects in contact (more than contacts when the array was full)
  std::int32_t deepest = -1;           ///< index in the array of the deepest contact (-1: none)
  double maxDepth = 0.0;               ///< the largest depth over all touched objects
  Vec3 penetration = Vec3::Zero();     ///< sum over contacts of depth * world normal: force = stiffness * this
  std::uint32_t objectsQueried = 0;    ///< objects whose bound the pointer reached (their detector ran)
  std::uint32_t objectsRejected = 0;   ///< objects rejected by the scene-level bound, no sphere touched
  std::uint32_t objectsInactive = 0;   ///< objects skipped because they have no pose yet
  std::uint32_t bruteForce = 0;        ///< objects answered by the brute-force reference (no level yet)
};

/**
 * \brief Collision detection of one pointer against a scene of objects, each with its own CLOD
 * detector and a world-from-object pose.
 *
 * Skips what the query does not need: each object's bounding sphere is kept in world coordinates in a
 * flat array, and an object whose bound is farther than the pointer radius is rejected before its
 * detector is touched. A surviving object gets the pointer transformed into its frame by a cached
 * inverse pose. Moving an object (setPose) updates two transforms and one bound; nothing is rebuilt.
 *
 * query() is const, allocation-free and noexcept. The mutators (addObject, setPose, setDetector,
 * setActive) must not run concurrently with a query: the owner updates poses and queries on one
 * thread (the ROS glue does both on the pose callback).
 */
class SceneDetector {
 public:
  /**
   * \brief Adds an object and returns its index. detector may be null (the level is not ready yet):
   * the object is then answered by the brute-force reference on its mesh until setDetector.
   * \throws InvalidParameter when mesh is null, the detector belongs to another mesh or the pose is
   * not finite or not rigid.
   */
  std::uint32_t addObject(std::string name, std::shared_ptr<const TriangleMesh> mesh,
                          std::shared_ptr<const ClodDetector> detector, const Eigen::Isometry3d& worldFromObject);

  /** \brief Moves object i: a new world-from-object pose, no rebuild. \throws InvalidParameter as addObject. */
  void setPose(std::uint32_t i, const Eigen::Isometry3d& worldFromObject);
  /** \brief Swaps object i's level (null: brute force). \throws InvalidParameter for another mesh's detector. */
  void setDetector(std::uint32_t i, std::shared_ptr<const ClodDetector> detector);
  /** \brief An inactive object (e.g. its frame is not known yet) is skipped by queries. Objects start active. */
  void setActive(std::uint32_t i, bool active);

  /**
   * \brief Answers which objects the pointer (world centre p, radius r) touches. Per touched object
   * a SceneContact goes to contacts[0 .. capacity) in object order; out combines them. caches, when
   * given, holds one QueryCache per object (size() of them) for temporal coherence.
   * A non-finite p or r, or a negative r, answers no contact.
   */
  void query(const Vec3& p, double r, DetectionMode mode, SceneContact* contacts, std::size_t capacity,
             SceneQueryResult& out, QueryCache* caches = nullptr) const noexcept;

  /** \brief Number of objects. */
  std::size_t size() const { return objects_.size(); }
  /** \brief Name of object i. */
  const std::string& name(std::uint32_t i) const { return objects_[i].name; }
  /** \brief Mesh of object i. */
  const std::shared_ptr<const TriangleMesh>& mesh(std::uint32_t i) const { return objects_[i].mesh; }
  /** \brief Level of object i (may be null). */
  const std::shared_ptr<const ClodDetector>& detector(std::uint32_t i) const { return objects_[i].detector; }
  /** \brief World-from-object pose of object i. */
  const Eigen::Isometry3d& pose(std::uint32_t i) const { return objects_[i].worldFromObject; }
  /** \brief Whether object i takes part in queries. */
  bool active(std::uint32_t i) const { return active_[i] != 0; }
  /** \brief Centre of object i's bounding sphere in the world frame. */
  Vec3 boundCentre(std::uint32_t i) const {
    return objects_[i].worldFromObject * objects_[i].mesh->toModel(objects_[i].localCentre);
  }
  /** \brief Radius of object i's bounding sphere. */
  double boundRadius(std::uint32_t i) const { return boundR_[i]; }

 private:
  struct Object {
    std::string name;
    std::shared_ptr<const TriangleMesh> mesh;
    std::shared_ptr<const ClodDetector> detector;
    Eigen::Isometry3d worldFromObject = Eigen::Isometry3d::Identity();
    Eigen::Isometry3d objectFromWorld = Eigen::Isometry3d::Identity();
    // Both in the mesh's local frame (its vertices' frame, TriangleMesh::origin away from the object frame),
    // where they and the spheres are exact for an object far from zero.
    Vec3 localCentre = Vec3::Zero();             ///< bounding-sphere centre
    Eigen::AlignedBox3d localBox;                ///< mesh bounds (second, tighter test)
    double radius = 0.0;                         ///< bounding-sphere radius, with its slack
    double boxGrow = 0.0;                        ///< how far the level's spheres reach beyond localBox
    EIGEN_MAKE_ALIGNED_OPERATOR_NEW
  };
  void updateBound(std::uint32_t i);
  void measureSpheres(std::uint32_t i);

  // The hot data of the rejection test, one array per coordinate so the test over all objects
  // vectorises: the world centre of each bounding sphere (NaN while the object is inactive, which no
  // comparison accepts) and its radius.
  std::vector<double> boundX_, boundY_, boundZ_, boundR_;
  std::vector<double> sphereGrow_;  // spheres mode: how far the level's spheres reach beyond boundR_
  std::vector<char> active_;
  std::uint32_t inactive_ = 0;
  std::vector<Object, Eigen::aligned_allocator<Object>> objects_;
};

}  // namespace clod_haptics
