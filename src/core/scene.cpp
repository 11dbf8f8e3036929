#include "clod_haptics/core/scene.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>

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

// Every scene state gets its own number, across all scenes: a stream's neighbourhood from one never serves another.
std::atomic<std::uint64_t> nextVersion{1};

}  // namespace

void SceneDetector::touch() { version_ = nextVersion.fetch_add(1, std::memory_order_relaxed); }

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
  // A little slack so rounding in the transform never rejects a touching pointer.
  object.radius = std::sqrt(radius2) * (1.0 + 1e-9) + 1e-12;
  const auto index = static_cast<std::uint32_t>(objects_.size());
  objects_.push_back(std::move(object));
  boundX_.push_back(0.0);
  boundY_.push_back(0.0);
  boundZ_.push_back(0.0);
  boundR_.push_back(0.0);
  sphereGrow_.push_back(0.0);
  active_.push_back(1);
  setPose(index, worldFromObject);
  measureSpheres(index);
  tree_.build(boundX_.data(), boundY_.data(), boundZ_.data(), boundR_.data(), sphereGrow_.data(), objects_.size());
  touch();
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
  const Vec3 c = object.worldFromObject * object.mesh->toModel(object.localCentre);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  // World coordinates far from zero round at their own magnitude (the centre here, the pointer's offset
  // from it in the test): slack of a few units in the last place of the largest coordinate.
  boundR_[i] = object.radius + 8.0 * std::numeric_limits<double>::epsilon() * c.cwiseAbs().maxCoeff();
  boundX_[i] = active_[i] ? c.x() : nan;
  boundY_[i] = active_[i] ? c.y() : nan;
  boundZ_[i] = active_[i] ? c.z() : nan;
  tree_.update(i, boundX_.data(), boundY_.data(), boundZ_.data(), boundR_.data(), sphereGrow_.data());
  touch();
}

void SceneDetector::setDetector(std::uint32_t i, std::shared_ptr<const ClodDetector> detector) {
  Object& object = objects_.at(i);
  if (detector && detector->mesh().get() != object.mesh.get()) {
    throw InvalidParameter("scene object '" + object.name + "': the detector was built for another mesh");
  }
  object.detector = std::move(detector);
  measureSpheres(i);
}

void SceneDetector::measureSpheres(std::uint32_t i) {
  // Spheres mode answers contact with a CLOD sphere, and a sphere reaches beyond the mesh's bound: how far, for
  // the sphere test and for the box test. The detector measured its spheres when it was built (O(spheres), off
  // the haptic path); localCentre and localBox are the same bounds it measured from.
  Object& object = objects_[i];
  double sphereGrow = 0.0, boxGrow = 0.0;
  if (object.detector) {
    sphereGrow = std::max(0.0, object.detector->spheresReachFromBoundsCentre() - object.radius);
    boxGrow = object.detector->spheresReachBeyondBounds();
  }
  sphereGrow_[i] = sphereGrow * (1.0 + 1e-9) + 1e-12;
  object.boxGrow = boxGrow * (1.0 + 1e-9) + 1e-12;
  tree_.update(i, boundX_.data(), boundY_.data(), boundZ_.data(), boundR_.data(), sphereGrow_.data());
  touch();
}

void SceneDetector::setActive(std::uint32_t i, bool active) {
  if (static_cast<bool>(active_.at(i)) == active) return;
  active_[i] = active;
  active ? --inactive_ : ++inactive_;
  updateBound(i);
}

void SceneDetector::query(const Vec3& p, double r, DetectionMode mode, SceneContact* contacts, std::size_t capacity,
                          SceneQueryResult& out, QueryCache* caches) const noexcept {
  out = SceneQueryResult();
  if (!validPointer(p, r)) return;
  const std::size_t n = objects_.size();
  out.objectsInactive = inactive_;
  // Scene-level rejection, a block of objects at a time: first the sphere test for the whole block
  // (branch-free, vectorised; an inactive object's NaN centre fails it), then only the survivors.
  constexpr std::size_t kBlock = 64;
  double margin[kBlock];  // squared distance minus squared reach: <= 0 when the pointer reaches the bound
  const double px = p.x(), py = p.y(), pz = p.z();
  const bool spheres = mode == DetectionMode::Spheres;
  for (std::size_t base = 0; base < n; base += kBlock) {
    const std::size_t m = std::min(kBlock, n - base);
    const double* __restrict bx = boundX_.data() + base;
    const double* __restrict by = boundY_.data() + base;
    const double* __restrict bz = boundZ_.data() + base;
    const double* __restrict br = boundR_.data() + base;
    const double* __restrict grow = sphereGrow_.data() + base;
    for (std::size_t k = 0; k < m; ++k)
      margin[k] = boundMargin(px, py, pz, bx[k], by[k], bz[k], br[k] + r + (spheres ? grow[k] : 0.0));
    for (std::size_t k = 0; k < m; ++k) {
      if (!(margin[k] <= 0.0)) {  // NaN (inactive) fails too
        if (caches) caches[base + k].lastInside = false;  // no contact: a later deep search would be stale
        continue;
      }
      const std::size_t i = base + k;
      queryObject(static_cast<std::uint32_t>(i), p, r, mode, contacts, capacity, out, caches ? &caches[i] : nullptr);
    }
  }
  out.objectsRejected = static_cast<std::uint32_t>(n) - out.objectsQueried - out.objectsInactive;
}

void SceneDetector::queryObject(std::uint32_t i, const Vec3& p, double r, DetectionMode mode, SceneContact* contacts,
                                std::size_t capacity, SceneQueryResult& out, QueryCache* cache) const noexcept {
  const bool spheres = mode == DetectionMode::Spheres;
  const Object& object = objects_[i];
  const Vec3 local = object.objectFromWorld * p;
  // The box is tighter than the sphere for long or flat objects; still no sphere touched.
  if (object.localBox.exteriorDistance(object.mesh->toLocal(local)) > r + (spheres ? object.boxGrow : 0.0)) {
    if (cache) cache->lastInside = false;
    return;
  }
  ++out.objectsQueried;
  ContactResult result;
  if (object.detector) {
    object.detector->query(local, r, mode, result, cache);
  } else if (cache && cache->lastInside && !spheres) {
    // The stream was inside this object: follow the push beyond r, as a detector with a cache does.
    result = bruteForceSignedQuery(*object.mesh, local, r);
    cache->lastInside = result.contact && result.inside;
    ++out.bruteForce;
  } else {
    result = bruteForceQuery(*object.mesh, local, r);
    if (cache) cache->lastInside = result.contact && result.inside && !spheres;
    ++out.bruteForce;
  }
  if (!result.contact) return;
  ++out.touched;
  out.contact = true;
  // depth is the signed penetration (r + distance with the centre inside): the summed spring grows
  // while the pointer pushes into any object, and maxDepth names the object pushed deepest.
  const Vec3 normal = object.worldFromObject.linear() * result.normal;
  out.penetration += result.depth * normal;
  if (out.contacts < capacity) {
    SceneContact& c = contacts[out.contacts];
    c.object = i;
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

void SceneDetector::query(const Vec3& p, double r, DetectionMode mode, SceneContact* contacts, std::size_t capacity,
                          SceneQueryResult& out, SceneCaches& caches) const noexcept {
  const std::size_t n = objects_.size();
  if (caches.objects.size() != n || caches.inside.size() != n || caches.insideCount > n) {
    query(p, r, mode, contacts, capacity, out, nullptr);
    return;
  }
  out = SceneQueryResult();
  if (!validPointer(p, r)) return;
  const bool spheres = mode == DetectionMode::Spheres;
  // The neighbourhood: still valid while the pointer stays within its margin of the anchor (an object outside it lay
  // farther than margin beyond the reach at the anchor), for this radius or a smaller one, in this state of the scene.
  if (!(caches.sceneVersion == version_ && r <= caches.anchorRadius && spheres == caches.anchorSpheres &&
        (p - caches.anchor).norm() <= caches.margin)) {
    caches.sceneVersion = 0;
    const double margin = kNearMargin * r;
    const std::size_t listed = tree_.candidates(p, r + margin, spheres, caches.near, SceneCaches::kNear);
    if (listed > SceneCaches::kNear) {  // a crowd: the flat scan, which touches every cache; redo the inside list
      query(p, r, mode, contacts, capacity, out, caches.objects.data());
      caches.insideCount = 0;
      for (std::uint32_t i = 0; i < n; ++i)
        if (caches.objects[i].lastInside) caches.inside[caches.insideCount++] = i;
      return;
    }
    std::sort(caches.near, caches.near + listed);  // contacts come in object order
    caches.nearCount = static_cast<std::uint32_t>(listed);
    caches.anchor = p;
    caches.anchorRadius = r;
    caches.anchorSpheres = spheres;
    // The tree's test is widened against rounding; the margin is shrunk by as much more, relative to the coordinates.
    caches.margin = margin * (1.0 - 1e-9) - 1e-12 * (p.cwiseAbs().maxCoeff() + r);
    caches.sceneVersion = version_;
  }
  out.objectsInactive = inactive_;
  // The bound test on the neighbours (the flat form's, value for value), in object order.
  std::uint32_t reached[SceneCaches::kNear];
  std::uint32_t count = 0;
  for (std::uint32_t k = 0; k < caches.nearCount; ++k)
    if (reaches(caches.near[k], p, r, spheres)) reached[count++] = caches.near[k];
  // A push the last answer followed into an object now out of reach ends (the flat form clears every cache).
  for (std::uint32_t k = 0; k < caches.insideCount; ++k) {
    const std::uint32_t i = caches.inside[k];
    if (!std::binary_search(reached, reached + count, i)) caches.objects[i].lastInside = false;
  }
  caches.insideCount = 0;
  for (std::uint32_t k = 0; k < count; ++k) {
    const std::uint32_t i = reached[k];
    queryObject(i, p, r, mode, contacts, capacity, out, &caches.objects[i]);
    if (caches.objects[i].lastInside) caches.inside[caches.insideCount++] = i;
  }
  out.objectsRejected = static_cast<std::uint32_t>(n) - out.objectsQueried - out.objectsInactive;
}

}  // namespace clod_haptics
