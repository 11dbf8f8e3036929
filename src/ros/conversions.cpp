#include "clod_haptics/ros/conversions.h"

#include <cmath>
#include <string>
#include <vector>

#include "clod_haptics/core/errors.h"

namespace clod_haptics {

namespace {
template <class Msg>
Msg xyz(const Vec3& v) {
  Msg m;
  m.x = v.x();
  m.y = v.y();
  m.z = v.z();
  return m;
}
}  // namespace

geometry_msgs::Point toPoint(const Vec3& v) { return xyz<geometry_msgs::Point>(v); }

geometry_msgs::Vector3 toVector3(const Vec3& v) { return xyz<geometry_msgs::Vector3>(v); }

Vec3 fromPoint(const geometry_msgs::Point& p) { return Vec3(p.x, p.y, p.z); }

void toMsg(const ClodSphereSet& set, const std_msgs::Header& header, SphereSet& msg) {
  msg.header = header;
  msg.mesh_name = set.meshName;
  msg.scale = set.scale;
  msg.distance = set.distance;
  msg.origin = toPoint(set.origin);
  msg.spheres.resize(set.size());
  for (std::size_t i = 0; i < set.size(); ++i) {
    Sphere& s = msg.spheres[i];
    s.center = toPoint(set.centres[i]);
    s.radius = set.radii[i];
    s.triangles.assign(set.begin(i), set.end(i));
  }
  const BuildStats& st = set.stats;
  msg.stats.triangles = static_cast<std::uint32_t>(st.triangles);
  msg.stats.centres = static_cast<std::uint32_t>(st.centres);
  msg.stats.spheres = static_cast<std::uint32_t>(st.spheres);
  msg.stats.unpaired = static_cast<std::uint32_t>(st.unpaired);
  msg.stats.degenerate = static_cast<std::uint32_t>(st.degenerate);
  msg.stats.max_triangles_per_sphere = static_cast<std::uint32_t>(st.maxTrianglesPerSphere);
  msg.stats.mean_triangles_per_sphere = st.meanTrianglesPerSphere;
  msg.stats.placement_ms = st.placementMs;
  msg.stats.clustering_ms = st.clusteringMs;
}

ClodSphereSet fromMsg(const SphereSet& msg) {
  ClodSphereSet set;
  set.meshName = msg.mesh_name;
  set.scale = msg.scale;
  set.distance = msg.distance;
  set.origin = fromPoint(msg.origin);
  if (!set.origin.allFinite()) throw FormatError("sphere set message: the origin is not finite");
  set.centres.reserve(msg.spheres.size());
  set.radii.reserve(msg.spheres.size());
  set.offsets.assign(1, 0);
  set.offsets.reserve(msg.spheres.size() + 1);
  std::size_t total = 0;
  for (const Sphere& s : msg.spheres) total += s.triangles.size();
  set.triangles.reserve(total);
  for (std::size_t i = 0; i < msg.spheres.size(); ++i) {
    const Sphere& s = msg.spheres[i];
    const Vec3 c = fromPoint(s.center);
    if (!c.allFinite() || !std::isfinite(s.radius) || s.radius < 0.0) {
      throw FormatError("sphere set message: sphere " + std::to_string(i) + " has a non-finite centre or a bad radius");
    }
    set.centres.push_back(c);
    set.radii.push_back(s.radius);
    set.triangles.insert(set.triangles.end(), s.triangles.begin(), s.triangles.end());
    set.offsets.push_back(static_cast<std::uint32_t>(set.triangles.size()));
  }
  set.stats.triangles = msg.stats.triangles;
  set.stats.centres = msg.stats.centres;
  set.stats.spheres = msg.stats.spheres;
  set.stats.unpaired = msg.stats.unpaired;
  set.stats.degenerate = msg.stats.degenerate;
  set.stats.maxTrianglesPerSphere = msg.stats.max_triangles_per_sphere;
  set.stats.meanTrianglesPerSphere = msg.stats.mean_triangles_per_sphere;
  set.stats.placementMs = msg.stats.placement_ms;
  set.stats.clusteringMs = msg.stats.clustering_ms;
  return set;
}

void toMsg(const ContactResult& result, const Vec3& pointer, double radius, Contact& msg) {
  msg.in_contact = result.contact;
  if (result.contact) {
    msg.point = toPoint(result.point);
    msg.normal = toVector3(result.normal);
    msg.distance = result.distance;
    msg.depth = result.depth;
    msg.inside = result.inside;
  } else {
    msg.point = geometry_msgs::Point();
    msg.normal = geometry_msgs::Vector3();
    msg.distance = 0.0;
    msg.depth = 0.0;
    msg.inside = false;
  }
  msg.triangle = result.contact ? result.triangle : -1;
  msg.sphere = result.contact ? result.sphere : -1;
  msg.spheres_hit = result.spheresHit;
  msg.triangles_tested = result.trianglesTested;
  msg.pointer = toPoint(pointer);
  msg.proxy = msg.pointer;  // the penalty model's; the proxy model sets its own
  msg.pointer_radius = radius;
}

geometry_msgs::Pose toPose(const Eigen::Isometry3d& pose) {
  geometry_msgs::Pose msg;
  msg.position = toPoint(pose.translation());
  const Eigen::Quaterniond q(pose.linear());
  msg.orientation.x = q.x();
  msg.orientation.y = q.y();
  msg.orientation.z = q.z();
  msg.orientation.w = q.w();
  return msg;
}

Eigen::Isometry3d toIsometry(const geometry_msgs::Transform& transform) {
  const auto& t = transform.translation;
  const auto& q = transform.rotation;
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.translate(Vec3(t.x, t.y, t.z));
  out.rotate(Eigen::Quaterniond(q.w, q.x, q.y, q.z).normalized());
  return out;
}

void toMsg(const Vec3& force, geometry_msgs::Wrench& msg) {
  msg.force = toVector3(force);
  msg.torque = geometry_msgs::Vector3();
}

bool isFinite(const geometry_msgs::Pose& pose) {
  const auto& p = pose.position;
  const auto& q = pose.orientation;
  return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z) && std::isfinite(q.x) && std::isfinite(q.y) &&
         std::isfinite(q.z) && std::isfinite(q.w);
}

}  // namespace clod_haptics
