// Pose-to-contact latency of the detector as users run it: launch/latency_benchmark.launch starts the
// shipped clod_haptics.launch with its defaults (sphere_builder, the detector nodelet in its manager), and
// this program, a separate process like any pose source, streams stylus poses at a fixed rate (1 kHz by
// default) on a coherent path near the mesh surface, subscribes to the markers like RViz would, and times
// each contact against its pose with the steady clock. Reports median, p90, p99, p99.9, max, unanswered and
// lost poses, and the detector's own pose-path percentiles (~status: roscpp receipt to answer published).
// A benchmark, not a test: it prints figures and never fails on them.
//
//   scripts/latency_benchmark.sh [duration:=60 mesh:=... scale:=...]
#include <geometry_msgs/PoseStamped.h>
#include <ros/callback_queue.h>
#include <ros/ros.h>
#include <visualization_msgs/MarkerArray.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cinttypes>
#include <cstdio>
#include <mutex>
#include <thread>
#include <vector>

#include "clod_haptics/Contact.h"
#include "clod_haptics/DetectorStatus.h"
#include "clod_haptics/core/mesh_loader.h"
#include "clod_haptics/core/probes.h"
#include "clod_haptics/ros/mesh_resource.h"

namespace {

std::int64_t nowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  const std::size_t k = std::min(v.size() - 1, static_cast<std::size_t>(q * (v.size() - 1) + 0.5));
  std::nth_element(v.begin(), v.begin() + k, v.end());
  return v[k];
}

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "latency_benchmark");
  ros::NodeHandle nh;
  ros::NodeHandle pnh("~");
  double duration = 60.0, rate = 1000.0, warmup = 3.0;
  std::string detectorName = "/detector";
  pnh.param("duration", duration, 60.0);
  pnh.param("rate", rate, 1000.0);
  pnh.param("warmup", warmup, 3.0);
  pnh.param<std::string>("detector", detectorName, "/detector");

  // The detector reads its parameters (mesh, scale, ...) from <detector>/...; the probes use the same mesh.
  std::string meshUri;
  double scale = 1.0;
  bool normalize = false;
  ros::NodeHandle dnh(detectorName);
  if (!dnh.getParam("mesh", meshUri)) {
    ROS_ERROR("latency_benchmark: set %s/mesh", detectorName.c_str());
    return 1;
  }
  dnh.param("scale", scale, 1.0);
  dnh.param("normalize", normalize, false);
  double radius = 0.002;
  dnh.param("pointer_radius", radius, 0.002);
  std::string frame;
  dnh.param<std::string>("frame_id", frame, "world");
  std::string poseTopic;
  dnh.param<std::string>("pose_topic", poseTopic, "/phantom/pose");
  clod_haptics::MeshLoadOptions options;
  options.scale = scale;
  options.normalize = normalize;
  const clod_haptics::TriangleMesh mesh = clod_haptics::loadMesh(clod_haptics::resolveMeshPath(meshUri), options);

  const std::size_t total = static_cast<std::size_t>(duration * rate);
  std::vector<std::int64_t> sentNs(total, 0), latencyNs(total, -1), queryNs(total, -1);
  std::vector<char> inContact(total, 0);
  std::atomic<std::uint64_t> received{0}, markerArrays{0};
  std::atomic<bool> measuring{false};

  // Contacts and markers on their own queue and thread.
  ros::CallbackQueue queue;
  ros::NodeHandle qnh;
  qnh.setCallbackQueue(&queue);
  const std::int64_t stampBase = 1000000000LL;  // measured pose i has stamp 1 s + i ns (warm-up: below 1 s)
  auto contactSub = qnh.subscribe<clod_haptics::Contact>(
      detectorName + "/contact", 10000,
      [&](const clod_haptics::ContactConstPtr& c) {
        const std::int64_t t = nowNs();
        if (!measuring) return;
        const std::int64_t i = static_cast<std::int64_t>(c->header.stamp.toNSec()) - stampBase;
        if (i < 0 || static_cast<std::size_t>(i) >= total) return;
        latencyNs[i] = t - sentNs[i];
        queryNs[i] = c->detection_time.toNSec();
        inContact[i] = c->in_contact;
        received.fetch_add(1);
      },
      ros::VoidConstPtr(), ros::TransportHints().tcpNoDelay());
  auto markerSub = qnh.subscribe<visualization_msgs::MarkerArray>(
      detectorName + "/markers", 10,
      [&](const visualization_msgs::MarkerArrayConstPtr&) { markerArrays.fetch_add(1); });
  ros::AsyncSpinner spinner(1, &queue);
  spinner.start();
  ros::AsyncSpinner globalSpinner(1);
  globalSpinner.start();

  ros::Publisher posePub = nh.advertise<geometry_msgs::PoseStamped>(poseTopic, 1000);

  // A coherent path: near-surface probes in Morton order, walked back and forth.
  std::vector<clod_haptics::Vec3> path = clod_haptics::nearSurfaceProbes(mesh, 20000, 2.0 * radius, 7);
  clod_haptics::sortMorton(path);

  // Wait for the first level (status latched) and the connections.
  ros::NodeHandle snh;
  std::atomic<std::uint32_t> levelSpheres{0};
  std::mutex statusMutex;
  clod_haptics::DetectorStatus lastStatus;
  auto statusSub = snh.subscribe<clod_haptics::DetectorStatus>(
      detectorName + "/status", 1, [&](const clod_haptics::DetectorStatusConstPtr& s) {
        levelSpheres = s->level_spheres;
        std::lock_guard<std::mutex> lock(statusMutex);
        lastStatus = *s;
      });
  const auto waitStart = std::chrono::steady_clock::now();
  while (ros::ok() && (levelSpheres == 0 || posePub.getNumSubscribers() == 0 || markerSub.getNumPublishers() == 0)) {
    if (std::chrono::steady_clock::now() - waitStart > std::chrono::seconds(120)) {
      ROS_ERROR("latency_benchmark: the detector did not come up (level, subscriptions)");
      return 1;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  ROS_INFO("latency_benchmark: level with %u spheres ready; %zu triangles; warming up %.0f s", levelSpheres.load(),
           mesh.size(), warmup);

  const auto period = std::chrono::nanoseconds(static_cast<std::int64_t>(1e9 / rate));
  auto publishPose = [&](std::size_t k, std::int64_t stampNs) {
    auto pose = boost::make_shared<geometry_msgs::PoseStamped>();
    pose->header.frame_id = frame;
    pose->header.stamp.fromNSec(static_cast<std::uint64_t>(stampNs));
    const auto& p = path[(k / path.size()) % 2 == 0 ? k % path.size() : path.size() - 1 - k % path.size()];
    pose->pose.position.x = p.x();
    pose->pose.position.y = p.y();
    pose->pose.position.z = p.z();
    pose->pose.orientation.w = 1.0;
    return pose;
  };
  // Warm-up (not measured): stamps below stampBase.
  auto next = std::chrono::steady_clock::now();
  const std::size_t warmCount = static_cast<std::size_t>(warmup * rate);
  for (std::size_t k = 0; k < warmCount && ros::ok(); ++k) {
    next += period;
    posePub.publish(publishPose(k, 1000 + static_cast<std::int64_t>(k)));
    std::this_thread::sleep_until(next);
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  const std::uint64_t markersBefore = markerArrays.load();
  measuring = true;
  const auto streamStart = std::chrono::steady_clock::now();
  next = streamStart;
  for (std::size_t i = 0; i < total && ros::ok(); ++i) {
    next += period;
    auto pose = publishPose(warmCount + i, stampBase + static_cast<std::int64_t>(i));
    sentNs[i] = nowNs();
    posePub.publish(pose);
    std::this_thread::sleep_until(next);
  }
  const double streamed = std::chrono::duration<double>(std::chrono::steady_clock::now() - streamStart).count();
  std::this_thread::sleep_for(std::chrono::seconds(2));  // late answers still count; a status after the last pose
  measuring = false;
  clod_haptics::DetectorStatus status;
  {
    std::lock_guard<std::mutex> lock(statusMutex);
    status = lastStatus;
  }
  const std::uint64_t markerCount = markerArrays.load() - markersBefore;

  std::vector<double> lat, query;
  std::size_t unanswered = 0, contacts = 0;
  for (std::size_t i = 0; i < total; ++i) {
    if (latencyNs[i] < 0) {
      ++unanswered;
      continue;
    }
    lat.push_back(latencyNs[i] * 1e-3);
    query.push_back(queryNs[i] * 1e-3);
    contacts += inContact[i] ? 1 : 0;
  }
  std::printf("\n== latency_benchmark: the detector nodelet of clod_haptics.launch, poses from another process ==\n");
  std::printf("mesh %s: %zu triangles, scale %g%s; level: %u spheres; pointer radius %g\n", mesh.name.c_str(),
              mesh.size(), scale, normalize ? " (normalised)" : "", levelSpheres.load(), radius);
  std::printf("poses sent %zu at %.0f Hz over %.1f s; answered %zu; unanswered %zu; in contact %zu (%.1f %%)\n", total,
              rate, streamed, lat.size(), unanswered, contacts, lat.empty() ? 0.0 : 100.0 * contacts / lat.size());
  std::printf("marker arrays received while streaming: %" PRIu64 " (%.1f Hz)\n", markerCount, markerCount / streamed);
  std::printf("pose -> contact latency (us): median %.1f  p90 %.1f  p99 %.1f  p99.9 %.1f  max %.1f\n",
              percentile(lat, 0.5), percentile(lat, 0.9), percentile(lat, 0.99), percentile(lat, 0.999),
              lat.empty() ? 0.0 : *std::max_element(lat.begin(), lat.end()));
  std::printf("core query alone (us):         median %.2f  p99 %.2f  max %.2f\n", percentile(query, 0.5),
              percentile(query, 0.99), query.empty() ? 0.0 : *std::max_element(query.begin(), query.end()));
  std::printf("detector status: pose policy %s, queues %u/%u, received %" PRIu64 ", answered %" PRIu64
              ", lost upstream %" PRIu64 ", skipped stale %" PRIu64 "\n",
              status.pose_policy.c_str(), status.pose_queue_size, status.publish_queue_size, status.poses_received,
              status.contacts_published, status.poses_lost_upstream, status.poses_skipped_stale);
  std::printf("in-node pose path (us, receipt -> answer published, whole run): p50 %.0f  p99 %.0f  p99.9 %.0f  max %.0f\n",
              status.pose_path_p50_us, status.pose_path_p99_us, status.pose_path_p999_us, status.pose_path_max_us);
  std::printf("targets (set for a pose source in the detector's process; these poses cross processes over TCP): "
              "median < 50 us %s, p99 < 250 us %s, unanswered == 0 %s\n",
              percentile(lat, 0.5) < 50 ? "met" : "MISSED", percentile(lat, 0.99) < 250 ? "met" : "MISSED",
              unanswered == 0 ? "met" : "MISSED");
  std::fflush(stdout);
  spinner.stop();
  globalSpinner.stop();
  ros::shutdown();
  return 0;
}
