#include "clod_haptics/core/swept_scene.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "clod_haptics/core/contact.h"
#include "clod_haptics/core/errors.h"

namespace clod_haptics {
namespace {

void checkPose(const Eigen::Isometry3d& pose) {
  const Eigen::Matrix3d rotation = pose.linear();
  const bool rigid = (rotation.transpose() * rotation).isIdentity(1e-6) && rotation.determinant() > 0.0;
  if (!pose.matrix().allFinite() || !rigid)
    throw InvalidParameter("SweptScene: the pose is not a finite rigid transform");
}

// Squared distance from c to the segment a -> b.
double squaredDistanceToSegment(const Vec3& c, const Vec3& a, const Vec3& b) {
  return (c - closestPointOnSegment(c, a, b)).squaredNorm();
}

// An object's answer in the world frame.
SweptContact toWorld(const Eigen::Isometry3d& worldFromObject, const SweptContact& c) {
  SweptContact out = c;
  out.centre = worldFromObject * c.centre;
  out.point = worldFromObject * c.point;
  out.normal = worldFromObject.linear() * c.normal;
  return out;
}

}  // namespace

std::uint32_t SweptScene::add(std::shared_ptr<const SweptSphereQuery> query, const Eigen::Isometry3d& worldFromObject) {
  if (!query) throw InvalidParameter("SweptScene: null query");
  checkPose(worldFromObject);
  Object o;
  o.query = std::move(query);
  o.worldFromObject = worldFromObject;
  o.objectFromWorld = worldFromObject.inverse();
  objects_.push_back(o);
  for (std::vector<double>* v : {&boundX_, &boundY_, &boundZ_, &boundR_}) v->push_back(0.0);
  const auto index = static_cast<std::uint32_t>(objects_.size() - 1);
  updateBound(index);
  tree_.build(boundX_.data(), boundY_.data(), boundZ_.data(), boundR_.data(), nullptr, objects_.size());
  return index;
}

void SweptScene::setPose(std::uint32_t i, const Eigen::Isometry3d& worldFromObject) {
  checkPose(worldFromObject);
  Object& o = objects_.at(i);
  o.worldFromObject = worldFromObject;
  o.objectFromWorld = worldFromObject.inverse();
  updateBound(i);
}

void SweptScene::setActive(std::uint32_t i, bool active) {
  objects_.at(i).active = active;
  updateBound(i);
}

void SweptScene::setQuery(std::uint32_t i, std::shared_ptr<const SweptSphereQuery> query) {
  if (!query) throw InvalidParameter("SweptScene: null query");
  objects_.at(i).query = std::move(query);
  updateBound(i);
}

void SweptScene::updateBound(std::uint32_t i) {
  Object& o = objects_[i];
  const TriangleMesh& mesh = *o.query->mesh();
  const Eigen::AlignedBox3d box = mesh.bounds();
  o.boundCentre = o.worldFromObject * mesh.toModel(box.center());
  // Half the diagonal bounds every vertex; the margin covers the pose's rounding.
  o.boundRadius = 0.5 * box.diagonal().norm() * (1.0 + 1e-9) + 1e-9 * o.boundCentre.cwiseAbs().maxCoeff();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  boundX_[i] = o.active ? o.boundCentre.x() : nan;
  boundY_[i] = o.active ? o.boundCentre.y() : nan;
  boundZ_[i] = o.active ? o.boundCentre.z() : nan;
  boundR_[i] = o.boundRadius;
  tree_.update(i, boundX_.data(), boundY_.data(), boundZ_.data(), boundR_.data(), nullptr);
}

bool SweptScene::blocksAtStart(std::int32_t object, std::int32_t triangle, const Vec3& a, const Vec3& b, double r,
                               SceneSweptContact& out, double within) const noexcept {
  if (object < 0 || static_cast<std::size_t>(object) >= objects_.size()) return false;
  const Object& o = objects_[static_cast<std::size_t>(object)];
  SweptContact c;
  if (!o.active || !o.query->blocksAtStart(triangle, o.objectFromWorld * a, o.objectFromWorld * b, r, c, within))
    return false;
  out.contact = toWorld(o.worldFromObject, c);
  out.object = object;
  return true;
}

bool SweptScene::sweepObject(std::size_t i, const Vec3& a, const Vec3& b, double r, std::int32_t hintTriangle,
                             SweptContact& c) const noexcept {
  const Object& o = objects_[i];
  if (!o.active) return false;
  const double reach = o.boundRadius + r * (1.0 + 1e-9);
  if (!(squaredDistanceToSegment(o.boundCentre, a, b) <= reach * reach)) return false;
  o.query->sweep(o.objectFromWorld * a, o.objectFromWorld * b, r, c, hintTriangle);
  return true;
}

void SweptScene::sweep(const Vec3& a, const Vec3& b, double r, SceneSweptContact& out, std::int32_t hintObject,
                       std::int32_t hintTriangle) const noexcept {
  out = SceneSweptContact{};
  const std::size_t n = objects_.size();
  const bool hinted = hintObject >= 0 && static_cast<std::size_t>(hintObject) < n;
  // The objects to try: every one, or those the tree lists for the ball around the segment's middle that holds the
  // capsule (everything within r of the segment lies within r + half its length of the middle), when they fit.
  std::uint32_t near[64];
  std::size_t count = n;
  bool listed = false;
  if (n > kTreeAbove && a.allFinite() && b.allFinite() && std::isfinite(r)) {
    const Vec3 middle = 0.5 * (a + b);
    const double reach = r * (1.0 + 1e-9) + 0.5 * (b - a).norm() * (1.0 + 1e-9) + 1e-12 * middle.cwiseAbs().maxCoeff();
    const std::size_t found = tree_.candidates(middle, reach, false, near, 64);
    if (found <= 64) {
      std::sort(near, near + found);
      count = found;
      listed = true;
    }
  }
  SweptContact c;
  // One object's answer folded in; true when it is the answer outright (the hint's triangle blocking at 0).
  auto visit = [&](std::size_t i) {
    const bool isHint = hinted && i == static_cast<std::size_t>(hintObject);
    if (!sweepObject(i, a, b, r, isHint ? hintTriangle : -1, c)) return false;
    const std::uint32_t tested = out.contact.trianglesTested + c.trianglesTested;
    out.contact.trianglesTested = tested;
    const bool heldByHint = isHint && c.hit && c.toi == 0.0 && c.triangle == hintTriangle;
    // Ties to the lowest object (the hint's is tried first, out of order).
    const bool earlier = out.object < 0 || c.toi < out.contact.toi ||
                         (c.toi == out.contact.toi && static_cast<std::int32_t>(i) < out.object);
    if (!c.hit || !(heldByHint || earlier)) return false;
    out.contact = toWorld(objects_[i].worldFromObject, c);
    out.contact.trianglesTested = tested;
    out.object = static_cast<std::int32_t>(i);
    return heldByHint;
  };
  // The hint's object first, its query given the hint: when it answers with the hinted triangle at 0 (its tie rule),
  // that is the answer across objects too, and no other object is searched. The others in index order.
  const bool hintListed =
      hinted && (!listed || std::binary_search(near, near + count, static_cast<std::uint32_t>(hintObject)));
  if (hintListed && visit(static_cast<std::size_t>(hintObject))) return;
  for (std::size_t k = 0; k < count; ++k) {
    const std::size_t i = listed ? near[k] : k;
    if (hintListed && i == static_cast<std::size_t>(hintObject)) continue;  // tried first
    if (visit(i)) return;
  }
}

bool SweptScene::clearAt(const Vec3& p, double r) const noexcept {
  if (!validPointer(p, r)) return false;
  for (const Object& o : objects_) {
    if (!o.active) continue;
    const Vec3 local = o.objectFromWorld * p;
    if (const auto& detector = o.query->detector()) {
      QueryCache deep;  // "the last answer was inside": the query follows the nearest triangle beyond r
      deep.lastInside = true;
      ContactResult c;
      detector->query(local, r, DetectionMode::Exact, c, &deep);
      if (c.contact) return false;
    } else {
      const double reach = o.boundRadius + r * (1.0 + 1e-9);
      if (!((p - o.boundCentre).squaredNorm() <= reach * reach)) continue;
      SweptContact c;
      o.query->sweep(local, local, r, c);
      if (c.hit) return false;
    }
  }
  return true;
}

Vec3 SweptScene::shadedNormal(std::uint32_t i, std::int32_t t, const Vec3& worldPoint) const noexcept {
  const Object& o = objects_[i];
  const TriangleMesh& mesh = *o.query->mesh();
  const std::size_t ti = static_cast<std::size_t>(t);
  const Vec3 face = o.worldFromObject.linear() * mesh.normals[ti];
  // Barycentric weights of the point (projected on the plane) from the sub-triangle areas.
  const Vec3 p = mesh.toLocal(o.objectFromWorld * worldPoint);
  const Vec3 &v0 = mesh.vertex(ti, 0), &v1 = mesh.vertex(ti, 1), &v2 = mesh.vertex(ti, 2);
  const Vec3 n = (v1 - v0).cross(v2 - v0);
  const double nn = n.squaredNorm();
  if (!(nn > 0.0)) return face;
  Vec3 shaded = Vec3::Zero();
  const Vec3* v[3] = {&v0, &v1, &v2};
  for (int k = 0; k < 3; ++k) {
    const double w = std::max(0.0, (*v[(k + 2) % 3] - *v[(k + 1) % 3]).cross(p - *v[(k + 1) % 3]).dot(n) / nn);
    const Vec3 corner = pseudoNormal(mesh, static_cast<std::uint32_t>(ti), {TriangleFeature::Vertex, std::uint8_t(k)});
    const double len = corner.norm();
    shaded += w * (len > 0.0 ? Vec3(corner / len) : mesh.normals[ti]);
  }
  const double len = shaded.norm();
  return len > 0.0 ? Vec3(o.worldFromObject.linear() * (shaded / len)) : face;
}

}  // namespace clod_haptics
