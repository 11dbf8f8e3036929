#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <memory>
#include <vector>

#include "clod_haptics/core/bound_tree.h"
#include "clod_haptics/core/swept_query.h"

namespace clod_haptics {

/** \brief The first contact of a sweep over a scene: the object's answer, in the world frame. */
struct SceneSweptContact {
  SweptContact contact;      ///< toi, triangle, region, flags; centre, point and normal in the world frame
  std::int32_t object = -1;  ///< the object hit (-1: none)
};

/**
 * \brief The objects that constrain one haptic proxy: per object a SweptSphereQuery and a world-from-object
 * pose. A sweep goes to every object whose bounding sphere the swept capsule reaches (the segment moved into
 * the object's frame by a cached inverse pose; a rigid pose keeps the radius and the time of impact), and the
 * earliest contact wins (ties to the lower object index). Beyond kTreeAbove objects those are found through a box
 * tree over the bounds (BoundTree, refitted when an object moves): a sweep near one object of fifty tests a few
 * bounds, not fifty.
 *
 * sweep() is const, allocation-free and noexcept; the mutators must not run concurrently with it.
 */
class SweptScene {
 public:
  /**
   * \brief Adds an object, returns its index.
   * \throws InvalidParameter when query is null or the pose is not finite or not rigid.
   */
  std::uint32_t add(std::shared_ptr<const SweptSphereQuery> query, const Eigen::Isometry3d& worldFromObject);
  /** \brief Moves object i. \throws InvalidParameter as add. */
  void setPose(std::uint32_t i, const Eigen::Isometry3d& worldFromObject);
  /** \brief Swaps object i's query (a new level of the same part). \throws InvalidParameter when null. */
  void setQuery(std::uint32_t i, std::shared_ptr<const SweptSphereQuery> query);
  /** \brief An inactive object is skipped by sweeps (e.g. its pose is unknown). Objects start active. */
  void setActive(std::uint32_t i, bool active);

  /**
   * \brief The first contact of the sphere (radius r) moving a -> b in the world frame, over all objects, ties to
   * the lowest object. hint: a likely first contact (object and triangle, as SweptSphereQuery::sweep's hint; -1:
   * none); when that triangle blocks the sweep at toi = 0 it is the answer, whatever other objects touch.
   */
  void sweep(const Vec3& a, const Vec3& b, double r, SceneSweptContact& out, std::int32_t hintObject = -1,
             std::int32_t hintTriangle = -1) const noexcept;

  /**
   * \brief Whether triangle t of object i blocks the sweep (world frame) at toi = 0, as
   * SweptSphereQuery::blocksAtStart; then out is what sweep answers with that hint, and true. False for an inactive
   * or unknown object. A proxy checks its last constraints this way before it searches. within: as
   * SweptSphereQuery::blocksAtStart's (a distance, the same in both frames).
   */
  bool blocksAtStart(std::int32_t object, std::int32_t triangle, const Vec3& a, const Vec3& b, double r,
                     SceneSweptContact& out, double within = 0.0) const noexcept;

  /**
   * \brief Whether a proxy of radius r may start at the world point p: it touches no active object, and lies
   * inside none (an object whose query has a detector is searched beyond r for the nearest triangle, as
   * ClodDetector::query does for a stream that was inside; an object without one is only checked within r).
   * Allocation-free, noexcept.
   */
  bool clearAt(const Vec3& p, double r) const noexcept;

  /**
   * \brief The normal at a world point of triangle t of object i interpolated from its corners' angle-weighted
   * vertex normals (barycentric weights of the point), in the world frame: what force shading renders.
   * Falls back to the face normal on a mesh without adjacency or a degenerate triangle.
   */
  Vec3 shadedNormal(std::uint32_t i, std::int32_t t, const Vec3& worldPoint) const noexcept;

  /** \brief Number of objects. */
  std::size_t size() const { return objects_.size(); }
  /** \brief Above this many objects, sweeps find the bounds they may reach through the tree over them. */
  static constexpr std::size_t kTreeAbove = 4;
  /** \brief Query of object i. */
  const std::shared_ptr<const SweptSphereQuery>& query(std::uint32_t i) const { return objects_[i].query; }
  /** \brief World-from-object pose of object i. */
  const Eigen::Isometry3d& pose(std::uint32_t i) const { return objects_[i].worldFromObject; }

 private:
  struct Object {
    std::shared_ptr<const SweptSphereQuery> query;
    Eigen::Isometry3d worldFromObject = Eigen::Isometry3d::Identity();
    Eigen::Isometry3d objectFromWorld = Eigen::Isometry3d::Identity();
    Vec3 boundCentre = Vec3::Zero();  ///< bounding sphere in the world frame
    double boundRadius = 0.0;
    bool active = true;
    EIGEN_MAKE_ALIGNED_OPERATOR_NEW
  };
  void updateBound(std::uint32_t i);
  /** The sweep's test of object i: whether it is active and the capsule reaches its bound; then its answer. */
  bool sweepObject(std::size_t i, const Vec3& a, const Vec3& b, double r, std::int32_t hintTriangle,
                   SweptContact& c) const noexcept;
  std::vector<Object, Eigen::aligned_allocator<Object>> objects_;
  // The bounds again, one array per coordinate, for the tree (NaN centre: inactive), and the tree over them.
  std::vector<double> boundX_, boundY_, boundZ_, boundR_;
  BoundTree tree_;
};

}  // namespace clod_haptics
