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
#include "clod_haptics/ros/node_main.h"

namespace {

using clod_haptics::Vec3;

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

double maxOf(const std::vector<double>& v) { return v.empty() ? 0.0 : *std::max_element(v.begin(), v.end()); }

/** The benchmark's parameters (~duration, ~rate, ~warmup, ~detector) and the detector's that it mirrors. */
struct Settings {
  double duration = 60.0, rate = 1000.0, warmup = 3.0;
  std::string detectorName = "/detector";
  std::string meshUri;
  double scale = 1.0;
  bool normalize = false;
  double radius = 0.002;
  std::string frame;
  std::string poseTopic;
};

/** Reads the settings; false (logged) when the detector has no mesh parameter. */
bool readSettings(Settings& s) {
  ros::NodeHandle pnh("~");
  pnh.param("duration", s.duration, 60.0);
  pnh.param("rate", s.rate, 1000.0);
  pnh.param("warmup", s.warmup, 3.0);
  pnh.param<std::string>("detector", s.detectorName, "/detector");
  // The detector reads its parameters (mesh, scale, ...) from <detector>/...; the probes use the same mesh.
  ros::NodeHandle dnh(s.detectorName);
  if (!dnh.getParam("mesh", s.meshUri)) {
    ROS_ERROR("latency_benchmark: set %s/mesh", s.detectorName.c_str());
    return false;
  }
  dnh.param("scale", s.scale, 1.0);
  dnh.param("normalize", s.normalize, false);
  dnh.param("pointer_radius", s.radius, 0.002);
  dnh.param<std::string>("frame_id", s.frame, "world");
  dnh.param<std::string>("pose_topic", s.poseTopic, "/phantom/pose");
  return true;
}

clod_haptics::TriangleMesh loadDetectorMesh(const Settings& s) {
  clod_haptics::MeshLoadOptions options;
  options.scale = s.scale;
  options.normalize = s.normalize;
  return clod_haptics::loadMesh(clod_haptics::resolveMeshPath(s.meshUri), options);
}

/** What one measured run gives: latencies of the answered poses and the detector's last status. */
struct RunResult {
  std::vector<double> latencyUs, queryUs;
  std::size_t unanswered = 0, contacts = 0;
  double streamedS = 0.0;
  std::uint64_t markerArrays = 0;
  clod_haptics::DetectorStatus status;
};

/**
 * Streams poses to the detector and times each contact against its pose. Contacts and markers arrive on
 * their own queue and thread; measured pose i has stamp 1 s + i ns, so its contact names it (warm-up poses
 * are stamped below 1 s).
 */
class LatencyBenchmark {
 public:
  LatencyBenchmark(const Settings& settings, clod_haptics::TriangleMesh mesh)
      : settings_(settings),
        mesh_(std::move(mesh)),
        total_(static_cast<std::size_t>(settings.duration * settings.rate)),
        sentNs_(total_, 0),
        latencyNs_(total_, -1),
        queryNs_(total_, -1),
        inContact_(total_, 0) {
    subscribeToAnswers();
    posePub_ = nh_.advertise<geometry_msgs::PoseStamped>(settings_.poseTopic, 1000);
    // A coherent path: near-surface probes in Morton order, walked back and forth.
    path_ = clod_haptics::nearSurfaceProbes(mesh_, 20000, 2.0 * settings_.radius, 7);
    clod_haptics::sortMorton(path_);
    statusSub_ = nh_.subscribe<clod_haptics::DetectorStatus>(settings_.detectorName + "/status", 1,
                                                             &LatencyBenchmark::onStatus, this);
  }

  /** Waits for the first level (status latched) and the connections; false (logged) after 120 s. */
  bool waitForDetector() {
    const auto waitStart = std::chrono::steady_clock::now();
    while (ros::ok() &&
           (levelSpheres_ == 0 || posePub_.getNumSubscribers() == 0 || markerSub_.getNumPublishers() == 0)) {
      if (std::chrono::steady_clock::now() - waitStart > std::chrono::seconds(120)) {
        ROS_ERROR("latency_benchmark: the detector did not come up (level, subscriptions)");
        return false;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    ROS_INFO("latency_benchmark: level with %u spheres ready; %zu triangles; warming up %.0f s", levelSpheres_.load(),
             mesh_.size(), settings_.warmup);
    return true;
  }

  /** Streams warmup seconds of poses that are not measured. */
  void warmUp() {
    auto next = std::chrono::steady_clock::now();
    warmCount_ = static_cast<std::size_t>(settings_.warmup * settings_.rate);
    for (std::size_t k = 0; k < warmCount_ && ros::ok(); ++k) {
      next += period();
      posePub_.publish(pose(k, 1000 + static_cast<std::int64_t>(k)));
      std::this_thread::sleep_until(next);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }

  /** Streams the measured poses and collects the answers. */
  RunResult measure() {
    RunResult run;
    const std::uint64_t markersBefore = markerArrays_.load();
    measuring_ = true;
    const auto streamStart = std::chrono::steady_clock::now();
    auto next = streamStart;
    for (std::size_t i = 0; i < total_ && ros::ok(); ++i) {
      next += period();
      auto msg = pose(warmCount_ + i, kStampBase + static_cast<std::int64_t>(i));
      sentNs_[i] = nowNs();
      posePub_.publish(msg);
      std::this_thread::sleep_until(next);
    }
    run.streamedS = std::chrono::duration<double>(std::chrono::steady_clock::now() - streamStart).count();
    std::this_thread::sleep_for(std::chrono::seconds(2));  // late answers still count; a status after the last pose
    measuring_ = false;
    {
      std::lock_guard<std::mutex> lock(statusMutex_);
      run.status = lastStatus_;
    }
    run.markerArrays = markerArrays_.load() - markersBefore;
    collect(run);
    return run;
  }

  /** Prints the figures of run. */
  void report(const RunResult& run) const;

  /** Stops the spinners. */
  void stop() {
    spinner_.stop();
    globalSpinner_.stop();
  }

 private:
  static constexpr std::int64_t kStampBase = 1000000000LL;

  void subscribeToAnswers() {
    answersNh_.setCallbackQueue(&queue_);
    contactSub_ = answersNh_.subscribe<clod_haptics::Contact>(settings_.detectorName + "/contact", 10000,
                                                              &LatencyBenchmark::onContact, this,
                                                              ros::TransportHints().tcpNoDelay());
    markerSub_ = answersNh_.subscribe<visualization_msgs::MarkerArray>(
        settings_.detectorName + "/markers", 10,
        [this](const visualization_msgs::MarkerArrayConstPtr&) { markerArrays_.fetch_add(1); });
    spinner_.start();
    globalSpinner_.start();
  }

  void onContact(const clod_haptics::ContactConstPtr& c) {
    const std::int64_t t = nowNs();
    if (!measuring_) return;
    const std::int64_t i = static_cast<std::int64_t>(c->header.stamp.toNSec()) - kStampBase;
    if (i < 0 || static_cast<std::size_t>(i) >= total_) return;
    latencyNs_[i] = t - sentNs_[i];
    queryNs_[i] = c->detection_time.toNSec();
    inContact_[i] = c->in_contact;
  }

  void onStatus(const clod_haptics::DetectorStatusConstPtr& s) {
    levelSpheres_ = s->level_spheres;
    std::lock_guard<std::mutex> lock(statusMutex_);
    lastStatus_ = *s;
  }

  std::chrono::nanoseconds period() const {
    return std::chrono::nanoseconds(static_cast<std::int64_t>(1e9 / settings_.rate));
  }

  /** Pose k of the path, walked back and forth, with the given stamp. */
  geometry_msgs::PoseStampedPtr pose(std::size_t k, std::int64_t stampNs) const {
    auto msg = boost::make_shared<geometry_msgs::PoseStamped>();
    msg->header.frame_id = settings_.frame;
    msg->header.stamp.fromNSec(static_cast<std::uint64_t>(stampNs));
    const std::size_t n = path_.size();
    const Vec3& p = path_[(k / n) % 2 == 0 ? k % n : n - 1 - k % n];
    msg->pose.position.x = p.x();
    msg->pose.position.y = p.y();
    msg->pose.position.z = p.z();
    msg->pose.orientation.w = 1.0;
    return msg;
  }

  /** The latencies of the answered poses into run. */
  void collect(RunResult& run) const {
    for (std::size_t i = 0; i < total_; ++i) {
      if (latencyNs_[i] < 0) {
        ++run.unanswered;
        continue;
      }
      run.latencyUs.push_back(latencyNs_[i] * 1e-3);
      run.queryUs.push_back(queryNs_[i] * 1e-3);
      run.contacts += inContact_[i] ? 1 : 0;
    }
  }

  const Settings settings_;
  const clod_haptics::TriangleMesh mesh_;
  const std::size_t total_;
  std::size_t warmCount_ = 0;
  std::vector<std::int64_t> sentNs_, latencyNs_, queryNs_;
  std::vector<char> inContact_;
  std::atomic<std::uint64_t> markerArrays_{0};
  std::atomic<bool> measuring_{false};
  std::atomic<std::uint32_t> levelSpheres_{0};
  std::mutex statusMutex_;
  clod_haptics::DetectorStatus lastStatus_;

  ros::NodeHandle nh_;
  ros::CallbackQueue queue_;
  ros::NodeHandle answersNh_;
  ros::Subscriber contactSub_, markerSub_;
  ros::AsyncSpinner spinner_{1, &queue_};
  ros::AsyncSpinner globalSpinner_{1};
  ros::Publisher posePub_;
  std::vector<Vec3> path_;
  ros::Subscriber statusSub_;
};

void LatencyBenchmark::report(const RunResult& run) const {
  const Settings& s = settings_;
  const std::vector<double>& lat = run.latencyUs;
  const clod_haptics::DetectorStatus& status = run.status;
  std::printf("\n== latency_benchmark: the detector nodelet of clod_haptics.launch, poses from another process ==\n");
  std::printf("mesh %s: %zu triangles, scale %g%s; level: %u spheres; pointer radius %g\n", mesh_.name.c_str(),
              mesh_.size(), s.scale, s.normalize ? " (normalised)" : "", levelSpheres_.load(), s.radius);
  std::printf("poses sent %zu at %.0f Hz over %.1f s; answered %zu; unanswered %zu; in contact %zu (%.1f %%)\n", total_,
              s.rate, run.streamedS, lat.size(), run.unanswered, run.contacts,
              lat.empty() ? 0.0 : 100.0 * run.contacts / lat.size());
  std::printf("marker arrays received while streaming: %" PRIu64 " (%.1f Hz)\n", run.markerArrays,
              run.markerArrays / run.streamedS);
  std::printf("pose -> contact latency (us): median %.1f  p90 %.1f  p99 %.1f  p99.9 %.1f  max %.1f\n",
              percentile(lat, 0.5), percentile(lat, 0.9), percentile(lat, 0.99), percentile(lat, 0.999), maxOf(lat));
  std::printf("core query alone (us):         median %.2f  p99 %.2f  max %.2f\n", percentile(run.queryUs, 0.5),
              percentile(run.queryUs, 0.99), maxOf(run.queryUs));
  std::printf("detector status: pose policy %s, queues %u/%u, received %" PRIu64 ", answered %" PRIu64
              ", lost upstream %" PRIu64 ", skipped stale %" PRIu64 "\n",
              status.pose_policy.c_str(), status.pose_queue_size, status.publish_queue_size, status.poses_received,
              status.contacts_published, status.poses_lost_upstream, status.poses_skipped_stale);
  std::printf(
      "in-node pose path (us, receipt -> answer published, whole run): p50 %.0f  p99 %.0f  p99.9 %.0f  max %.0f\n",
      status.pose_path_p50_us, status.pose_path_p99_us, status.pose_path_p999_us, status.pose_path_max_us);
  std::printf(
      "targets (set for a pose source in the detector's process; these poses cross processes over TCP): "
      "median < 50 us %s, p99 < 250 us %s, unanswered == 0 %s\n",
      percentile(lat, 0.5) < 50 ? "met" : "MISSED", percentile(lat, 0.99) < 250 ? "met" : "MISSED",
      run.unanswered == 0 ? "met" : "MISSED");
  std::fflush(stdout);
}

}  // namespace

int main(int argc, char** argv) {
  clod_haptics::lineBufferStdout();
  ros::init(argc, argv, "latency_benchmark");
  ros::NodeHandle nh;  // the node runs while a NodeHandle exists
  Settings settings;
  if (!readSettings(settings)) return 1;
  LatencyBenchmark benchmark(settings, loadDetectorMesh(settings));
  if (!benchmark.waitForDetector()) return 1;
  benchmark.warmUp();
  benchmark.report(benchmark.measure());
  benchmark.stop();
  ros::shutdown();
  return 0;
}
