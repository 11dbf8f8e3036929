#include "clod_haptics/ros/markers.h"

#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

#include "clod_haptics/ros/conversions.h"

namespace clod_haptics {

namespace {

visualization_msgs::Marker baseMarker(const char* ns, int id, int type, const std_msgs::Header& header) {
  visualization_msgs::Marker m;
  m.header = header;
  m.ns = ns;
  m.id = id;
  m.type = type;
  m.action = visualization_msgs::Marker::ADD;
  m.pose.orientation.w = 1.0;
  m.scale.x = m.scale.y = m.scale.z = 1.0;
  m.frame_locked = true;
  return m;
}

}  // namespace

std_msgs::ColorRGBA makeColor(float r, float g, float b, float a) {
  std_msgs::ColorRGBA c;
  c.r = r;
  c.g = g;
  c.b = b;
  c.a = a;
  return c;
}

visualization_msgs::Marker meshMarker(const TriangleMesh& mesh, const std_msgs::Header& header,
                                      const std_msgs::ColorRGBA& color) {
  visualization_msgs::Marker m = baseMarker(marker_ns::kMesh, 0, visualization_msgs::Marker::TRIANGLE_LIST, header);
  m.color = color;
  m.points.reserve(mesh.size() * 3);
  for (std::size_t t = 0; t < mesh.size(); ++t) {
    for (int k = 0; k < 3; ++k) m.points.push_back(toPoint(mesh.toModel(mesh.vertex(t, k))));
  }
  return m;
}

std::size_t appendSphereMarkers(const ClodSphereSet& set, const std::vector<std::uint32_t>* indices, const char* ns,
                                const std_msgs::Header& header, const std_msgs::ColorRGBA& color,
                                std::size_t previousCount, visualization_msgs::MarkerArray& out) {
  // (radius class, sphere) pairs, sorted by class: each run of one class becomes one list.
  std::vector<std::pair<int, std::uint32_t>> byClass;
  const std::size_t n = indices ? indices->size() : set.size();
  byClass.reserve(n);
  for (std::size_t k = 0; k < n; ++k) {
    const std::size_t i = indices ? (*indices)[k] : k;
    if (i >= set.size() || !std::isfinite(set.radii[i]) || !set.centres[i].allFinite()) continue;
    const double r = std::max(set.radii[i], 1e-12);
    byClass.emplace_back(static_cast<int>(std::ceil(kSphereClassesPerOctave * std::log2(r))),
                         static_cast<std::uint32_t>(i));
  }
  std::sort(byClass.begin(), byClass.end());
  std::size_t written = 0;
  for (std::size_t a = 0; a < byClass.size();) {
    std::size_t b = a;
    while (b < byClass.size() && byClass[b].first == byClass[a].first) ++b;
    visualization_msgs::Marker m =
        baseMarker(ns, static_cast<int>(written), visualization_msgs::Marker::SPHERE_LIST, header);
    const double radius = std::exp2(static_cast<double>(byClass[a].first) / kSphereClassesPerOctave);
    m.scale.x = m.scale.y = m.scale.z = 2.0 * radius;
    m.color = color;
    m.points.reserve(b - a);
    for (std::size_t k = a; k < b; ++k) m.points.push_back(toPoint(set.centres[byClass[k].second] + set.origin));
    out.markers.push_back(std::move(m));
    ++written;
    a = b;
  }
  for (std::size_t k = written; k < previousCount; ++k)
    out.markers.push_back(deleteMarker(ns, static_cast<int>(k), header));
  return written;
}

visualization_msgs::Marker pointerMarker(const Vec3& p, double radius, const std_msgs::Header& header,
                                         const std_msgs::ColorRGBA& color, const char* ns) {
  visualization_msgs::Marker m = baseMarker(ns, 0, visualization_msgs::Marker::SPHERE, header);
  m.pose.position = toPoint(p);
  m.scale.x = m.scale.y = m.scale.z = 2.0 * radius;
  m.color = color;
  return m;
}

void appendContactMarkers(const ContactResult& result, double arrowLength, const std_msgs::Header& header,
                          visualization_msgs::MarkerArray& out) {
  if (!result.contact) {
    out.markers.push_back(deleteMarker(marker_ns::kContact, 0, header));
    out.markers.push_back(deleteMarker(marker_ns::kNormal, 0, header));
    return;
  }
  visualization_msgs::Marker point = baseMarker(marker_ns::kContact, 0, visualization_msgs::Marker::SPHERE, header);
  point.pose.position = toPoint(result.point);
  point.scale.x = point.scale.y = point.scale.z = 0.12 * arrowLength;
  point.color = makeColor(1.0f, 0.0f, 1.0f, 1.0f);
  out.markers.push_back(std::move(point));

  visualization_msgs::Marker arrow = baseMarker(marker_ns::kNormal, 0, visualization_msgs::Marker::ARROW, header);
  arrow.points.push_back(toPoint(result.point));
  arrow.points.push_back(toPoint(result.point + arrowLength * result.normal));
  arrow.scale.x = 0.06 * arrowLength;  // shaft diameter
  arrow.scale.y = 0.15 * arrowLength;  // head diameter
  arrow.scale.z = 0.25 * arrowLength;  // head length
  arrow.color = makeColor(1.0f, 0.9f, 0.0f, 1.0f);
  out.markers.push_back(std::move(arrow));
}

visualization_msgs::Marker forceMarker(const Vec3& from, const Vec3& force, double lengthPerNewton,
                                       const std_msgs::Header& header) {
  const double newtons = force.norm();
  if (!(newtons > 0.0) || !std::isfinite(newtons) || !from.allFinite()) return deleteMarker(marker_ns::kForce, 0, header);
  const double length = lengthPerNewton * std::min(newtons, 3.0);
  visualization_msgs::Marker arrow = baseMarker(marker_ns::kForce, 0, visualization_msgs::Marker::ARROW, header);
  arrow.points.push_back(toPoint(from));
  arrow.points.push_back(toPoint(from + (length / newtons) * force));
  arrow.scale.x = 0.06 * lengthPerNewton;  // shaft and head sized as the normal's, not by the force
  arrow.scale.y = 0.15 * lengthPerNewton;
  arrow.scale.z = std::min(0.25 * lengthPerNewton, 0.5 * length);
  arrow.color = makeColor(0.1f, 0.95f, 0.3f, 1.0f);
  return arrow;
}

visualization_msgs::Marker meshResourceMarker(const std::string& resource, const Eigen::Isometry3d& pose, double scale,
                                              const std_msgs::Header& header, const std_msgs::ColorRGBA& color) {
  visualization_msgs::Marker m = baseMarker("scene_mesh", 0, visualization_msgs::Marker::MESH_RESOURCE, header);
  m.mesh_resource = resource;
  m.pose = toPose(pose);
  m.scale.x = m.scale.y = m.scale.z = scale;
  m.color = color;
  m.frame_locked = true;
  return m;
}

void applyOffset(const Eigen::Isometry3d& offset, std::size_t first, visualization_msgs::MarkerArray& out) {
  for (std::size_t k = first; k < out.markers.size(); ++k) {
    visualization_msgs::Marker& m = out.markers[k];
    if (m.action != visualization_msgs::Marker::ADD) continue;
    if (m.type == visualization_msgs::Marker::SPHERE_LIST) {
      m.pose = toPose(offset);  // the list's points are in mesh coordinates: the pose carries the offset
    } else {
      m.pose.position = toPoint(offset * fromPoint(m.pose.position));
    }
  }
}

visualization_msgs::Marker deleteMarker(const char* ns, int id, const std_msgs::Header& header) {
  visualization_msgs::Marker m;
  m.header = header;
  m.ns = ns;
  m.id = id;
  m.action = visualization_msgs::Marker::DELETE;
  m.pose.orientation.w = 1.0;
  return m;
}

}  // namespace clod_haptics
