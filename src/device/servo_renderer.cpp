#include "clod_haptics/device/servo_renderer.h"

#include "clod_haptics/core/errors.h"

namespace clod_haptics {
namespace device {

ServoRenderer::ServoRenderer(std::shared_ptr<const SweptScene> scene, const ServoRenderSettings& settings)
    : scene_(std::move(scene)), renderer_(settings.proxy), current_(settings) {
  if (!scene_) throw InvalidParameter("ServoRenderer: null scene");
}

void ServoRenderer::configure(const ServoRenderSettings& settings) noexcept {
  settings_.back() = settings;
  settings_.publish();
}

bool ServoRenderer::render(const Eigen::Vector3d& devicePosition, double time, Eigen::Vector3d& force,
                           double stamp) noexcept {
  force.setZero();
  if (settings_.update()) {
    const ServoRenderSettings& next = settings_.front();
    // Another radius, or the device seen from elsewhere: the proxy starts again from a clear point.
    if (next.proxy.radius != current_.proxy.radius || next.sceneFromDevice.matrix() != current_.sceneFromDevice.matrix() ||
        !next.enabled)
      active_ = false;
    current_ = next;
    renderer_.setParameters(current_.proxy);
  }
  if (!current_.enabled) return false;
  ServoRenderTick& out = ticks_.back();
  out.time = time;
  out.stamp = stamp;
  out.frame = ++frame_;
  const Vec3 p = current_.sceneFromDevice * devicePosition;
  if (!active_ && p.allFinite() && scene_->clearAt(p, current_.proxy.radius)) {
    renderer_.reset(p);
    active_ = true;
    lastTime_ = time;
  }
  out.active = active_;
  if (active_) {
    const double dt = time > lastTime_ ? time - lastTime_ : 1e-3;
    lastTime_ = time;
    renderer_.update(*scene_, p, dt, out.tick);
    force = current_.sceneFromDevice.linear().transpose() * out.tick.force;
  } else {
    out.tick = ProxyTick{};
    out.tick.device = p;
    out.tick.proxy = p;
  }
  out.deviceForce = force;
  ticks_.publish();
  return true;
}

bool ServoRenderer::latest(ServoRenderTick& out) noexcept {
  if (!ticks_.update()) return false;
  out = ticks_.front();
  return true;
}

}  // namespace device
}  // namespace clod_haptics
