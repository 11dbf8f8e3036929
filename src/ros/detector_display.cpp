#include "clod_haptics/ros/detector_display.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include "clod_haptics/ros/markers.h"

namespace clod_haptics {

namespace {
const ClodSphereSet& spheresOf(const ClodDetector* level) {
  static const ClodSphereSet empty;
  return level ? *level->spheres() : empty;
}

/**
 * A colour per level, from its clustering distance d: the hue turns by a third per doubling of d (1 mm blue), so a
 * new level shows as a new colour; translucent, so the mesh stays visible through the spheres.
 */
std_msgs::ColorRGBA levelColor(double distance) {
  const double turns = distance > 0.0 ? std::log2(distance / 0.001) / 3.0 : 0.0;
  const double hue = 6.0 * (turns - std::floor(turns));  // [0, 6): 0 blue, 2 green, 4 red
  const auto channel = [hue](double centre) {
    double d = std::fabs(hue - centre);
    d = std::min(d, 6.0 - d);
    return static_cast<float>(std::clamp(2.0 - d, 0.0, 1.0));
  };
  return makeColor(channel(4.0), channel(2.0), channel(0.0), 0.12f);
}
}  // namespace

DetectorDisplay::DetectorDisplay(std::string sceneFrame,
                                 std::vector<DisplayObject, Eigen::aligned_allocator<DisplayObject>> objects,
                                 bool singleMesh)
    : sceneFrame_(std::move(sceneFrame)), objects_(std::move(objects)), singleMesh_(singleMesh) {
  const std::size_t n = objects_.size();
  shownLevelIds_.assign(n, 0);
  shownSpheres_.assign(n, 0);
  shownHit_.assign(n, 0);
  shownContact_.assign(n, 0);
  for (const DisplayObject& o : objects_)
    if (o.mesh) modelSize_ = std::max(modelSize_, o.mesh->diagonal());
}

double DetectorDisplay::arrowLength(double radius) const {
  return modelSize_ > 0.0 ? 0.08 * modelSize_ : std::max(8.0 * radius, 0.01);
}

void DetectorDisplay::setSwitches(const DisplaySwitches& switches) {
  meshSwitched_ |= switches.mesh != switches_.mesh;
  spheresSwitched_ |= switches.spheres != switches_.spheres;
  switches_ = switches;
}

std::string DetectorDisplay::ns(const char* base, std::size_t object) const {
  return singleMesh_ ? std::string(base) : std::string(base) + "/" + objects_[object].name;
}

std_msgs::Header DetectorDisplay::objectHeader(std::size_t object) const {
  std_msgs::Header header;
  header.frame_id = objects_[object].frameId;
  return header;
}

void DetectorDisplay::update(const std::vector<std::shared_ptr<const ClodDetector>>& levels, const DisplayFrame& frame,
                             visualization_msgs::MarkerArray& out) {
  const bool everything = everything_;
  const bool meshes = everything || meshSwitched_;
  const bool spheres = everything || spheresSwitched_;
  everything_ = meshSwitched_ = spheresSwitched_ = false;
  const bool newPose = frame.seq != 0 && (frame.seq != shownSeq_ || everything);
  for (std::size_t i = 0; i < objects_.size(); ++i) {
    if (!objects_[i].drawn) continue;
    const ClodDetector* level = i < levels.size() ? levels[i].get() : nullptr;
    if (meshes) appendMesh(i, out);
    if (spheres || (level ? level->id() : 0) != shownLevelIds_[i]) appendLevel(i, level, out);
    if (newPose) {
      appendHits(i, level, frame, out);
      appendContact(i, frame, out);
    }
  }
  if (!newPose) return;
  shownSeq_ = frame.seq;
  appendPointer(frame, out);
}

void DetectorDisplay::appendPointer(const DisplayFrame& frame, visualization_msgs::MarkerArray& out) const {
  std_msgs::Header header;
  header.frame_id = sceneFrame_;
  const bool touching = !frame.contacts.empty();
  out.markers.push_back(switches_.contact && touching ? forceMarker(frame.pointer, frame.force,
                                                                    arrowLength(frame.radius), header)
                                                      : deleteMarker(marker_ns::kForce, 0, header));
  if (!switches_.pointer) {
    out.markers.push_back(deleteMarker(marker_ns::kPointer, 0, header));
    out.markers.push_back(deleteMarker(marker_ns::kProxy, 0, header));
    return;
  }
  // The device point: translucent, so the contact point inside it shows.
  out.markers.push_back(
      pointerMarker(frame.pointer, frame.radius, header,
                    touching ? makeColor(1.0f, 0.2f, 0.2f, 0.55f) : makeColor(0.1f, 0.9f, 0.2f, 0.7f)));
  // The proxy stays on the surface while the device point sinks in: drawn beside it in blue.
  out.markers.push_back(frame.haveProxy ? pointerMarker(frame.proxy, frame.radius, header,
                                                        makeColor(0.2f, 0.45f, 1.0f, 0.8f), marker_ns::kProxy)
                                        : deleteMarker(marker_ns::kProxy, 0, header));
}

void DetectorDisplay::appendMesh(std::size_t i, visualization_msgs::MarkerArray& out) const {
  const DisplayObject& o = objects_[i];
  const std_msgs::Header header = objectHeader(i);
  const char* ns = singleMesh_ ? marker_ns::kMesh : "scene_mesh";
  if (!switches_.mesh) {
    out.markers.push_back(deleteMarker(ns, static_cast<int>(i), header));
    return;
  }
  const auto grey = makeColor(0.75f, 0.75f, 0.78f, 1.0f);
  if (singleMesh_) {
    out.markers.push_back(meshMarker(*o.mesh, header, grey));
  } else {
    out.markers.push_back(meshResourceMarker(o.meshResource, o.offset, o.scale, header, grey));
    out.markers.back().id = static_cast<int>(i);
  }
}

void DetectorDisplay::appendLevel(std::size_t i, const ClodDetector* level, visualization_msgs::MarkerArray& out) {
  static const ClodSphereSet empty;
  const std::size_t first = out.markers.size();
  const ClodSphereSet& set = switches_.spheres ? spheresOf(level) : empty;
  shownSpheres_[i] = appendSphereMarkers(set, nullptr, ns(marker_ns::kSpheres, i).c_str(), objectHeader(i),
                                         levelColor(set.distance), shownSpheres_[i], out);
  applyOffset(objects_[i].offset, first, out);
  for (std::size_t k = first; k < out.markers.size(); ++k) out.markers[k].frame_locked = true;
  shownLevelIds_[i] = level ? level->id() : 0;
}

void DetectorDisplay::appendHits(std::size_t i, const ClodDetector* level, const DisplayFrame& frame,
                                 visualization_msgs::MarkerArray& out) {
  hitBuffer_.clear();
  if (level && switches_.hitSpheres && i < frame.near.size() && frame.near[i]) {
    level->hitSpheres(frame.poses[i].inverse(Eigen::Isometry) * frame.pointer, frame.radius, hitBuffer_);
  }
  if (hitBuffer_.empty() && shownHit_[i] == 0) return;
  const std::size_t first = out.markers.size();
  shownHit_[i] = appendSphereMarkers(spheresOf(level), &hitBuffer_, ns(marker_ns::kHitSpheres, i).c_str(),
                                     objectHeader(i), makeColor(1.0f, 0.5f, 0.0f, 0.3f), shownHit_[i], out);
  applyOffset(objects_[i].offset, first, out);
}

void DetectorDisplay::appendContact(std::size_t i, const DisplayFrame& frame, visualization_msgs::MarkerArray& out) {
  const SceneContact* contact = nullptr;
  for (const SceneContact& c : frame.contacts)
    if (c.object == i) contact = &c;
  if (!switches_.contact) contact = nullptr;
  if (!contact && !shownContact_[i]) return;
  ContactResult shown;
  if (contact) {
    shown = contact->local;
    shown.point = contact->point;  // scene frame
    shown.normal = contact->normal;
  }
  std_msgs::Header header;
  header.frame_id = sceneFrame_;
  const std::size_t first = out.markers.size();
  appendContactMarkers(shown, arrowLength(frame.radius), header, out);
  for (std::size_t k = first; k < out.markers.size(); ++k) out.markers[k].id = static_cast<int>(i);
  shownContact_[i] = contact != nullptr;
}

}  // namespace clod_haptics
