#pragma once

#include <cstdint>

#include "clod_haptics/core/swept_scene.h"

namespace clod_haptics {

/** \brief The proxy's parameters (SI units). */
struct ProxyParameters {
  double radius = 0.002;     ///< proxy sphere radius (m)
  double stiffness = 400.0;  ///< spring between proxy and device (N/m)
  double damping = 0.0;      ///< on the proxy-device relative velocity while in contact (N s/m)
  double maxForce = 0.0;     ///< force magnitude clamp (N), 0 for none
  double muStatic = 0.0;     ///< static friction coefficient: the proxy sticks while |F_t| <= muStatic F_n
  double muDynamic = 0.0;    ///< dynamic friction coefficient (at most muStatic): a sliding proxy lags by muDynamic F_n
  bool forceShading =
      false;  ///< render the normal force along the interpolated vertex normal (smooth look of a coarse mesh)
};

/** \brief What one tick of the proxy answers. */
struct ProxyTick {
  Vec3 proxy = Vec3::Zero();          ///< proxy centre after the tick (world)
  Vec3 device = Vec3::Zero();         ///< device point of the tick
  Vec3 force = Vec3::Zero();          ///< force on the device (N): stiffness (proxy - device) + damping, clamped
  bool contact = false;               ///< a constraint held the proxy back this tick
  Vec3 point = Vec3::Zero();          ///< surface point of the first constraint (world), valid with contact
  Vec3 normal = Vec3::Zero();         ///< its unit normal, pointing from the surface towards the proxy
  std::int32_t object = -1;           ///< object of the first constraint
  std::int32_t triangle = -1;         ///< triangle of the first constraint
  std::uint32_t planes = 0;           ///< constraint planes active at the end of the solve (0 to 3)
  std::uint32_t sweeps = 0;           ///< swept queries run
  std::uint32_t trianglesTested = 0;  ///< exact triangle tests of those sweeps
  bool sticking = false;              ///< static friction held the proxy in place
  bool sliding = false;               ///< the proxy slid under dynamic friction
};

/**
 * \brief The god-object (proxy) haptic renderer (Zilles and Salisbury 1995, Ruspini et al. 1997): a sphere
 * that never penetrates the scene follows the device point, and the force is the spring between them.
 *
 * Each tick the proxy moves towards the device with SweptScene sweeps: it stops at the first contact, takes
 * the contact's normal as a constraint plane, moves its goal to the point nearest the device that satisfies
 * every plane found (up to three), and sweeps again, a bounded number of times. So it slides along faces,
 * into grooves and corners, and stops on a thin part however far the device went through it in one tick.
 * With friction, the first contact of a tick decides before any slide: a friction cone holds the proxy there
 * while the tangential force stays within muStatic times the normal force, and makes it lag behind by muDynamic
 * times the normal force while it slides.
 *
 * update() allocates nothing and never throws. One renderer per device; not shared between threads.
 */
class HapticRenderer {
 public:
  /** \brief A renderer with these parameters; the proxy starts at the first device point. */
  explicit HapticRenderer(const ProxyParameters& parameters = {}) { setParameters(parameters); }

  /** \brief Changes the parameters (negative values read as 0, muDynamic clamped to muStatic). */
  void setParameters(const ProxyParameters& parameters);
  /** \brief The parameters in use. */
  const ProxyParameters& parameters() const { return parameters_; }

  /**
   * \brief Places the proxy at position (free space assumed) and forgets the device's history; the next
   * update starts from there. Without a reset the first update places the proxy at the device point.
   */
  void reset(const Vec3& position);

  /**
   * \brief One haptic tick: moves the proxy towards device (world) under scene's constraints and computes the
   * force; dt (s) is the tick's length, used by damping only. A non-finite device point keeps the proxy
   * and answers zero force. A proxy that starts a tick inside an object (the object moved onto it, or the
   * first device point was inside) may leave it but not go deeper.
   */
  void update(const SweptScene& scene, const Vec3& device, double dt, ProxyTick& out) noexcept;

  /** \brief The proxy centre (world). */
  const Vec3& proxy() const { return proxy_; }

  /**
   * \brief While the proxy rests on something (a constraint of this tick or the last), a move shorter than this
   * many radii is not made, and a constraint that blocks the move within it blocks it at once (the proxy stays,
   * which enters nothing): the proxy lags its goal by at most this much (0.2 um for r = 2 mm, 80 uN at 400 N/m;
   * CHAI3D's finger proxy stops within 1e-5 m of its goal). Smaller, a proxy resting on a finely tessellated surface
   * spent a whole cell scan on moves of a few nanometres. A free proxy follows the device exactly; one that stays on
   * its constraints reports the tick in contact with them (no force without contact).
   */
  static constexpr double kStillRadii = 1e-4;

 private:
  struct Planes;
  enum class Friction { None, Stick, Slide };
  Vec3 solve(const SweptScene& scene, const Vec3& from, const Vec3& device, Planes& planes, ProxyTick& out);
  /**
   * The friction cone at the proxy's first contact of a tick (anchor), with the contact normal of planes and of the
   * last tick's constraints that still block there (added to planes): Stick (the proxy stays), Slide (target becomes
   * the point lagging the device by muDynamic times the push) or None (no push into the surface). still: the solve's
   * still distance (a constraint that blocks within it blocks at once).
   */
  Friction friction(const SweptScene& scene, const Vec3& anchor, const Vec3& device, double still, Planes& planes,
                    ProxyTick& out, Vec3& target);
  Vec3 force(const SweptScene& scene, const Vec3& device, double dt, const ProxyTick& tick) const;

  ProxyParameters parameters_;
  bool started_ = false;
  bool sliding_ = false;  // dynamic friction in effect since the last tick
  Vec3 proxy_ = Vec3::Zero();
  Vec3 lastProxy_ = Vec3::Zero();
  Vec3 lastDevice_ = Vec3::Zero();
  struct Hint {
    std::int32_t object = -1, triangle = -1;
  } hint_;  // the last contact: tested first by the next sweep
  Hint held_[3];       // the contacts that made the last tick's constraint planes
  int heldCount_ = 0;  // how many of held_ are in use
  // The first contact of the last tick that met one: a proxy that stays on its constraints (the still distance)
  // reports it again.
  Vec3 restPoint_ = Vec3::Zero(), restNormal_ = Vec3::Zero();
  std::int32_t restObject_ = -1, restTriangle_ = -1;
};

}  // namespace clod_haptics
