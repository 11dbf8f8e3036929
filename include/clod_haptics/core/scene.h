#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "clod_haptics/core/bound_tree.h"
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
 * \brief One pointer's stream of scene queries: a QueryCache per object, the objects whose cache its last answer left
 * inside (the only ones whose deep push a query may have to end), and the objects near where the stream was lately
 * (a pointer moves little between two queries: while it stays within `margin` of `anchor`, no other object's bound
 * can be reached, and the query tests those alone). Sized by resize() to the scene's object count (allocates);
 * SceneDetector::query with it allocates nothing. Owned by the caller, one per stream, not shared between threads.
 * Reset a stream with resize().
 */
struct SceneCaches {
  std::vector<QueryCache> objects;    ///< one per object, as query(..., QueryCache*) takes them
  std::vector<std::uint32_t> inside;  ///< [0, insideCount): every object whose cache says lastInside
  std::uint32_t insideCount = 0;
  /// The neighbourhood: near[0, nearCount) (ascending) holds every object whose bound lies within margin of the
  /// reach of a pointer of radius anchorRadius (spheres mode: with the spheres' reach) at anchor, in the scene
  /// whose state sceneVersion names (SceneDetector::version(); 0: none).
  static constexpr std::uint32_t kNear = 64;
  std::uint64_t sceneVersion = 0;
  Vec3 anchor = Vec3::Zero();
  double anchorRadius = 0.0, margin = 0.0;
  bool anchorSpheres = false;
  std::uint32_t nearCount = 0;
  std::uint32_t near[kNear] = {};
  /** \brief Fresh caches for a scene of n objects. */
  void resize(std::size_t n) {
    objects.assign(n, QueryCache());
    inside.assign(n, 0);
    insideCount = 0;
    sceneVersion = 0;
  }
};

/**
 * \brief Collision detection of one pointer against a scene of objects, each with its own CLOD
 * detector and a world-from-object pose.
 *
 * Skips what the query does not need: each object's bounding sphere is kept in world coordinates in a
 * flat array, and an object whose bound is farther than the pointer radius is rejected before its
 * detector is touched. A surviving object gets the pointer transformed into its frame by a cached
 * inverse pose. A stream's SceneCaches keeps the objects near its pointer, found through a box tree over the bounds
 * (BoundTree) and refreshed when the pointer has moved kNearMargin radii: a query near one object of fifty tests the
 * bounds of that neighbourhood, not fifty. Moving an object (setPose) updates two transforms, one bound and the
 * tree's path above it; nothing is rebuilt.
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
  /**
   * \brief The same with a stream's SceneCaches: the same answers as with caches.objects.data(), and the objects far
   * from the pointer are not touched at all (the array form writes every object's cache: ending a deep push needs to
   * know which objects the stream was inside, which the SceneCaches keeps). Caches sized for another object count
   * answer as without caches.
   */
  void query(const Vec3& p, double r, DetectionMode mode, SceneContact* contacts, std::size_t capacity,
             SceneQueryResult& out, SceneCaches& caches) const noexcept;

  /** \brief A stream's neighbourhood holds the objects within this many pointer radii of its reach. */
  static constexpr double kNearMargin = 8.0;
  /** \brief Names the scene's state: changed by every mutator (unique across scenes), what a SceneCaches checks. */
  std::uint64_t version() const { return version_; }

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
  /**
   * The bound test's value: squared distance from (px, py, pz) to a bound's centre minus its squared reach, <= 0
   * exactly when the pointer reaches it (a - b <= 0 exactly when a <= b); NaN (an inactive object) fails that test.
   * The flat scan and reaches() both compute it here, so they agree value for value.
   */
  static double boundMargin(double px, double py, double pz, double cx, double cy, double cz, double reach) {
    const double dx = px - cx, dy = py - cy, dz = pz - cz;
    return dx * dx + dy * dy + dz * dz - reach * reach;
  }
  /** Whether the pointer reaches object i's bounding sphere (NaN, inactive, does not). */
  bool reaches(std::uint32_t i, const Vec3& p, double r, bool spheres) const {
    return boundMargin(p.x(), p.y(), p.z(), boundX_[i], boundY_[i], boundZ_[i],
                       boundR_[i] + r + (spheres ? sphereGrow_[i] : 0.0)) <= 0.0;
  }
  /** One object whose bound the pointer reaches: its box test, its detector, and its share of out. */
  void queryObject(std::uint32_t i, const Vec3& p, double r, DetectionMode mode, SceneContact* contacts,
                   std::size_t capacity, SceneQueryResult& out, QueryCache* cache) const noexcept;

  // The hot data of the rejection test, one array per coordinate so the test over all objects
  // vectorises: the world centre of each bounding sphere (NaN while the object is inactive, which no
  // comparison accepts) and its radius.
  std::vector<double> boundX_, boundY_, boundZ_, boundR_;
  std::vector<double> sphereGrow_;  // spheres mode: how far the level's spheres reach beyond boundR_
  std::vector<char> active_;
  std::uint32_t inactive_ = 0;
  std::vector<Object, Eigen::aligned_allocator<Object>> objects_;
  BoundTree tree_;  // over the bounds above (their spheres-mode grow too), refitted by updateBound and measureSpheres
  std::uint64_t version_ = 0;  // see version(); set by touch()
  void touch();
};

}  // namespace clod_haptics
