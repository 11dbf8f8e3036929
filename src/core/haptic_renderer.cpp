#include "clod_haptics/core/haptic_renderer.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace clod_haptics {
namespace {

constexpr int kMaxPlanes = 3;
constexpr int kIterations = 6;  // sweeps per solve: one free move, or up to three planes and the slides between

}  // namespace

/**
 * The constraint planes of one solve (unit normals through the proxy) and the contacts that made them.
 */
struct HapticRenderer::Planes {
  Vec3 n[kMaxPlanes];
  Hint by[kMaxPlanes];
  int count = 0;
  /** Adds a plane unless one with the same normal is active (then false); a fourth replaces the oldest. */
  bool add(const Vec3& normal, const Hint& contact) {
    for (int i = 0; i < count; ++i)
      if (n[i].dot(normal) > 1.0 - 1e-12) return false;
    if (count == kMaxPlanes) {
      for (int i = 0; i + 1 < kMaxPlanes; ++i) {
        n[i] = n[i + 1];
        by[i] = by[i + 1];
      }
      count = kMaxPlanes - 1;
    }
    n[count] = normal;
    by[count++] = contact;
    return true;
  }
};

namespace {

// The point nearest target on the planes of mask (n_i . (x - p) = skin for i in mask), or false when they
// do not meet in one such point (parallel normals): x = target - sum_j lambda_j n_j, G lambda = c with G the
// Gram matrix of the active normals, solved in closed form (at most 3 x 3, by Cramer's rule).
bool projectOnto(const Vec3& target, const Vec3& p, const Vec3* n, unsigned mask, double skin, Vec3& x) {
  const Vec3* m[kMaxPlanes];
  int k = 0;
  for (int i = 0; i < kMaxPlanes; ++i)
    if (mask & (1u << i)) m[k++] = &n[i];
  x = target;
  if (k == 0) return true;
  double c[kMaxPlanes];
  for (int i = 0; i < k; ++i) c[i] = m[i]->dot(target - p) - skin;
  if (k == 1) {
    x -= c[0] * *m[0];  // unit normals: G = 1
    return true;
  }
  if (k == 2) {
    const double g = m[0]->dot(*m[1]), det = 1.0 - g * g;
    if (!(det > 1e-12)) return false;
    x -= ((c[0] - g * c[1]) / det) * *m[0] + ((c[1] - g * c[0]) / det) * *m[1];
    return true;
  }
  // Three planes: their one common point, solved directly: x with m_i . (x - p) = skin.
  const Vec3 a = m[1]->cross(*m[2]), b = m[2]->cross(*m[0]), e = m[0]->cross(*m[1]);
  const double det = m[0]->dot(a);
  if (!(std::abs(det) > 1e-12)) return false;
  x = p + (skin * (a + b + e)) / det;
  return x.allFinite();
}

// The point nearest target that keeps at least skin above every plane through p: target itself when it
// does, else the projection onto the subset of planes active at the optimum, found by trying every subset
// (at most seven) and keeping the nearest feasible answer. p itself when none is feasible.
Vec3 constrain(const Vec3& target, const Vec3& p, const Vec3* n, int count, double skin) {
  auto feasible = [&](const Vec3& x) {
    for (int i = 0; i < count; ++i)
      if (!(n[i].dot(x - p) >= 0.5 * skin)) return false;
    return true;
  };
  if (feasible(target)) return target;
  Vec3 best = p;
  double bestDistance = std::numeric_limits<double>::infinity();
  for (unsigned mask = 1; mask < (1u << count); ++mask) {
    Vec3 x;
    if (!projectOnto(target, p, n, mask, skin, x) || !feasible(x)) continue;
    const double distance = (x - target).squaredNorm();
    if (distance < bestDistance) {
      best = x;
      bestDistance = distance;
    }
  }
  return best;
}

}  // namespace

void HapticRenderer::setParameters(const ProxyParameters& parameters) {
  auto positive = [](double v) { return std::isfinite(v) && v > 0.0 ? v : 0.0; };
  parameters_ = parameters;
  parameters_.radius = positive(parameters.radius);
  parameters_.stiffness = positive(parameters.stiffness);
  parameters_.damping = positive(parameters.damping);
  parameters_.maxForce = positive(parameters.maxForce);
  parameters_.muStatic = positive(parameters.muStatic);
  parameters_.muDynamic = std::min(positive(parameters.muDynamic), parameters_.muStatic);
}

void HapticRenderer::reset(const Vec3& position) {
  proxy_ = lastProxy_ = lastDevice_ = position;
  started_ = true;
  sliding_ = false;
  heldCount_ = 0;
}

Vec3 HapticRenderer::solve(const SweptScene& scene, const Vec3& from, const Vec3& device, Planes& planes,
                           ProxyTick& out) {
  const double r = parameters_.radius;
  // The goal keeps this much above each plane: a slide then moves away from the surface it rests on by a
  // hair instead of into it by rounding, and the swept query lets it go.
  const double skin = 1e-9 * r + 1e-15 * from.cwiseAbs().maxCoeff();
  Vec3 p = from, goal = device;
  // Where the proxy heads: the device, or under dynamic friction the point that lags it (friction()).
  Vec3 target = device;
  bool frictionPending = parameters_.muStatic > 0.0;
  SceneSweptContact hit;
  // A move shorter than still (kStillRadii, and at least a few skins: the proxy wedged between its planes) is not
  // made while the proxy rests on something (a plane of this solve, or a constraint of the last tick): staying is as
  // good, never enters anything, and saves a sweep that would scan the cell for nothing (refined_elephant's
  // recording: p99 5.35 -> 4.19 to 4.25 us against 16 skins alone, bench/README.md). A free proxy makes every move
  // longer than a few skins, so it follows a device creeping through free space exactly: no force without contact.
  const double still = std::max(16.0 * skin, kStillRadii * r);
  const double freeStill = 16.0 * skin;
  double lift = 0.0;  // see below
  for (int i = 0; i < kIterations; ++i) {
    const double stay = planes.count > 0 || heldCount_ > 0 ? still : freeStill;
    if ((goal - p).squaredNorm() <= stay * stay) break;
    // The last tick's constraints first: one that still blocks at once answers the sweep without a search (a proxy
    // wedged in a crease meets the same two or three triangles every tick, each of them a search's worst case). The
    // proxy rests a skin above its planes, so "at once" is before it has moved still: it then stays where it is,
    // which enters nothing, and takes the plane as a sweep that met the triangle there would.
    bool blocked = false;
    for (int k = 0; k < heldCount_ && !blocked; ++k) {
      const Hint& h = held_[k];
      ++out.trianglesTested;
      blocked = scene.blocksAtStart(h.object, h.triangle, p, goal, r, hit, still);
    }
    if (!blocked) scene.sweep(p, goal, r, hit, hint_.object, hint_.triangle);
    ++out.sweeps;
    out.trianglesTested += blocked ? 0 : hit.contact.trianglesTested;
    if (!hit.contact.hit) return goal;
    hint_ = {hit.object, hit.contact.triangle};
    p = p + hit.contact.toi * (goal - p);
    if (!out.contact) {
      out.contact = true;
      out.point = hit.contact.point;
      out.normal = hit.contact.normal;
      out.object = hit.object;
      out.triangle = hit.contact.triangle;
    }
    if (!planes.add(hit.contact.normal, hint_) && hit.contact.toi == 0.0) {
      // A triangle in the plane of an active constraint blocks the slide along it at once: the proxy rests on the
      // line between two triangles of one plane (within the rounding margin of the second), and sliding over it
      // comes closer to the second by a rounding's worth. The same goal would meet it again every iteration: lift
      // the goal off that plane by a little more each time (1e-4 to 1e-2 of the slide; the proxy lands again
      // next tick).
      lift = lift == 0.0 ? 1e-4 : 10.0 * lift;
      goal = constrain(target, p, planes.n, planes.count, skin) + lift * (goal - p).norm() * hit.contact.normal;
      continue;
    }
    lift = 0.0;
    // Friction at the first contact, before any slide: a proxy that sticks stays there, one that slides heads for the
    // point that lags the device. (Deciding after a frictionless solve paid for its slides and threw them away: with
    // mu_s 0.3 the recording's ticks on refined_elephant cost 4 times the frictionless ones by the mean.)
    if (frictionPending) {
      frictionPending = false;
      if (friction(scene, p, device, still, planes, out, target) == Friction::Stick) return p;
    }
    goal = constrain(target, p, planes.n, planes.count, skin);
  }
  return p;
}

HapticRenderer::Friction HapticRenderer::friction(const SweptScene& scene, const Vec3& anchor, const Vec3& device,
                                                  double still, Planes& planes, ProxyTick& out, Vec3& target) {
  // The contact normal where the proxy stands: its planes so far, and the last tick's constraints it still rests on
  // (a proxy in a crease touches two or three; the search answered with one).
  const double r = parameters_.radius;
  SceneSweptContact hit;
  for (int k = 0; k < heldCount_ && planes.count < kMaxPlanes; ++k) {
    const Hint& h = held_[k];
    if (h.object == planes.by[0].object && h.triangle == planes.by[0].triangle) continue;
    ++out.trianglesTested;
    if (scene.blocksAtStart(h.object, h.triangle, anchor, device, r, hit, still)) planes.add(hit.contact.normal, h);
  }
  Vec3 normal = Vec3::Zero();
  for (int i = 0; i < planes.count; ++i) normal += planes.n[i];
  const double length = normal.norm();
  if (!(length > 1e-9)) return Friction::None;
  normal /= length;
  const Vec3 v = anchor - device;
  const double pressing = v.dot(normal);  // the normal force over the stiffness
  if (!(pressing > 0.0)) {
    sliding_ = false;
    return Friction::None;
  }
  const Vec3 tangential = v - pressing * normal;
  const double drag = tangential.norm();
  const double mu = sliding_ ? parameters_.muDynamic : parameters_.muStatic;
  if (drag <= mu * pressing) {  // inside the friction cone: the proxy stays where it touched
    sliding_ = false;
    out.sticking = true;
    return Friction::Stick;
  }
  // Sliding: the proxy follows to the dynamic cone's edge, lagging the device by muDynamic times the push.
  sliding_ = true;
  out.sliding = true;
  target = device + pressing * normal + tangential * (parameters_.muDynamic * pressing / drag);
  return Friction::Slide;
}

Vec3 HapticRenderer::force(const SweptScene& scene, const Vec3& device, double dt, const ProxyTick& tick) const {
  Vec3 f = parameters_.stiffness * (tick.proxy - device);
  if (parameters_.damping > 0.0 && dt > 0.0 && tick.contact)
    f += parameters_.damping * ((tick.proxy - lastProxy_) - (device - lastDevice_)) / dt;
  if (parameters_.forceShading && tick.contact && tick.planes == 1 && tick.object >= 0) {
    const double push = f.dot(tick.normal);
    if (push > 0.0)
      f +=
          push * (scene.shadedNormal(static_cast<std::uint32_t>(tick.object), tick.triangle, tick.point) - tick.normal);
  }
  const double magnitude = f.norm();
  if (parameters_.maxForce > 0.0 && magnitude > parameters_.maxForce) f *= parameters_.maxForce / magnitude;
  return f.allFinite() ? f : Vec3::Zero();
}

void HapticRenderer::update(const SweptScene& scene, const Vec3& device, double dt, ProxyTick& out) noexcept {
  out = ProxyTick{};
  out.device = device;
  out.proxy = proxy_;
  if (!device.allFinite()) return;
  if (!started_) reset(device);
  Planes planes;
  Vec3 p = solve(scene, proxy_, device, planes, out);
  // Stayed on the constraints it rested on (the device moved less than the still distance, in or off them: no sweep
  // ran): the proxy still touches them, and the tick says so with the last contact, so that no force (at most the
  // still distance times the stiffness) comes without contact. They stay held.
  const bool resting = !out.contact && out.sweeps == 0 && heldCount_ > 0 && restTriangle_ >= 0;
  if (resting) {
    out.contact = true;
    out.point = restPoint_;
    out.normal = restNormal_;
    out.object = restObject_;
    out.triangle = restTriangle_;
    out.planes = static_cast<std::uint32_t>(heldCount_);
  } else {
    out.planes = static_cast<std::uint32_t>(planes.count);
    heldCount_ = planes.count;
    std::copy(planes.by, planes.by + planes.count, held_);
    if (out.contact) {
      restPoint_ = out.point;
      restNormal_ = out.normal;
      restObject_ = out.object;
      restTriangle_ = out.triangle;
    }
  }
  if (!out.contact || !(parameters_.muStatic > 0.0)) sliding_ = false;
  proxy_ = p;
  out.proxy = p;
  out.force = force(scene, device, dt, out);
  lastProxy_ = p;
  lastDevice_ = device;
}

}  // namespace clod_haptics
