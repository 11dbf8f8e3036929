#include "clod_haptics/core/scene.h"

#include <algorithm>
#include <cmath>

#include "clod_haptics/core/brute_force.h"
#include "clod_haptics/core/errors.h"

namespace clod_haptics {

namespace {

void requireRigid(const Eigen::Isometry3d& pose, const std::string& name) {
  const Eigen::Matrix3d r = pose.linear();
  if (!pose.matrix().allFinite()) throw InvalidParameter("scene object '" + name + "': pose is not finite");
  if (!(r.transpose() * r).isIdentity(1e-6) || r.determinant() < 0.0) {
    throw InvalidParameter("scene object '" + name + "': pose is not a rigid transform (rotation + translation)");
  }
}

}  // namespace

std::uint32_t SceneDetector::addObject(std::string name, std::shared_ptr<const TriangleMesh> mesh,
                                       std::shared_ptr<const ClodDetector> detector,
                                       const Eigen::Isometry3d& worldFromObject) {
  if (!mesh || mesh->size() == 0) throw InvalidParameter("scene object '" + name + "': no mesh");
  if (detector && detector->mesh().get() != mesh.get()) {
    throw InvalidParameter("scene object '" + name + "': the detector was built for another mesh");
  }
  requireRigid(worldFromObject, name);
  Object object;
  object.name = std::move(name);
  object.mesh = std::move(mesh);
  object.detector = std::move(detector);
  // Bounding sphere: the box centre and the farthest referenced vertex from it.
  object.localBox = object.mesh->bounds();
  object.localCentre = object.localBox.center();
  double radius2 = 0.0;
  for (const Triangle& t : object.mesh->triangles)
    for (std::uint32_t v : t) radius2 = std::max(radius2, (object.mesh->vertices[v] - object.localCentre).squaredNorm());
  const auto index = static_cast<std::uint32_t>(objects_.size());
  objects_.push_back(std::move(object));
  // A little slack so rounding in the transform never rejects a touching pointer.
  const double radius = std::sqrt(radius2) * (1.0 + 1e-9) + 1e-12;
  bounds_.push_back(Bound{0.0, 0.0, 0.0, radius, true});
  setPose(index, worldFromObject);
  return index;
}

void SceneDetector::setPose(std::uint32_t i, const Eigen::Isometry3d& worldFromObject) {
  Object& object = objects_.at(i);
  requireRigid(worldFromObject, object.name);
  object.worldFromObject = worldFromObject;
  object.objectFromWorld = worldFromObject.inverse(Eigen::Isometry);
  updateBound(i);
}

void SceneDetector::updateBound(std::uint32_t i) {
  const Object& object = objects_[i];
  const Vec3 c = object.worldFromObject * object.localCentre;
  bounds_[i].x = c.x();
  bounds_[i].y = c.y();
  bounds_[i].z = c.z();
}

void SceneDetector::setDetector(std::uint32_t i, std::shared_ptr<const ClodDetector> detector) {
  Object& object = objects_.at(i);
  if (detector && detector->mesh().get() != object.mesh.get()) {
    throw InvalidParameter("scene object '" + object.name + "': the detector was built for another mesh");
  }
  object.detector = std::move(detector);
}

void SceneDetector::setActive(std::uint32_t i, bool active) { bounds_.at(i).active = active; }

void SceneDetector::query(const Vec3& p, double r, DetectionMode mode, SceneContact* contacts, std::size_t capacity,
                          SceneQueryResult& out, QueryCache* caches) const noexcept {
  out = SceneQueryResult();
  if (!p.allFinite() || !std::isfinite(r) || r < 0.0) return;
  const std::size_t n = bounds_.size();
  for (std::size_t i = 0; i < n; ++i) {
    const Bound& b = bounds_[i];
    if (!b.active) {
      ++out.objectsInactive;
      continue;
    }
    // Scene-level rejection: the pointer ball misses the object's bounding sphere.
    const double dx = p.x() - b.x, dy = p.y() - b.y, dz = p.z() - b.z;
    const double reach = b.radius + r;
    if (dx * dx + dy * dy + dz * dz > reach * reach) {
      ++out.objectsRejected;
      continue;
    }
    const Object& object = objects_[i];
    const Vec3 local = object.objectFromWorld * p;
    // The box is tighter than the sphere for long or flat objects; still no sphere touched.
    if (object.localBox.exteriorDistance(local) > r) {
      ++out.objectsRejected;
      continue;
    }
    ++out.objectsQueried;
    ContactResult result;
    if (object.detector) {
      object.detector->query(local, r, mode, result, caches ? &caches[i] : nullptr);
    } else {
      result = bruteForceQuery(*object.mesh, local, r);
      ++out.bruteForce;
    }
    if (!result.contact) continue;
    ++out.touched;
    out.contact = true;
    const Vec3 normal = object.worldFromObject.linear() * result.normal;
    out.penetration += result.depth * normal;
    if (out.contacts < capacity) {
      SceneContact& c = contacts[out.contacts];
      c.object = static_cast<std::uint32_t>(i);
      c.local = result;
      c.point = object.worldFromObject * result.point;
      c.normal = normal;
      if (out.deepest < 0 || result.depth > out.maxDepth) {
        out.deepest = static_cast<std::int32_t>(out.contacts);
        out.maxDepth = result.depth;
      }
      ++out.contacts;
    } else if (result.depth > out.maxDepth) {
      out.maxDepth = result.depth;  // deepest stays the deepest entry in the array
    }
  }
}

}  // namespace clod_haptics
