// rostest of the detector (node or nodelet, chosen by the .test file): poses in, contacts and forces
// out, each checked against the core's brute-force reference; bad inputs; tf2; reconfigure.
// Parameters (~): mesh, scale, normalize (same as the detector's), detector (its namespace),
// pose_frame (frame the test publishes poses in), mesh_in_pose_frame ([x y z yaw pitch roll], the
// mesh frame's pose in pose_frame as given to static_transform_publisher; empty: same frame).
#include <dynamic_reconfigure/Reconfigure.h>
#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/WrenchStamped.h>
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <tf2_ros/static_transform_broadcaster.h>
#include <visualization_msgs/MarkerArray.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <map>
#include <mutex>
#include <set>
#include <thread>

#include "clod_haptics/Contact.h"
#include "clod_haptics/DetectorStatus.h"
#include "clod_haptics/core/brute_force.h"
#include "clod_haptics/core/detector.h"
#include "clod_haptics/core/mesh_loader.h"
#include "clod_haptics/core/probes.h"
#include "clod_haptics/ros/mesh_resource.h"
#include "detector_answers.h"
#include "test_timing.h"

namespace clod_haptics {
namespace {

/** Talks to one detector: publishes poses with unique stamps and collects the answers by stamp. */
class DetectorClient {
 public:
  DetectorClient() : pnh_("~"), ns_(pnh_.param<std::string>("detector", "/detector")), answers_(ns_) {
    pnh_.param<std::string>("pose_frame", poseFrame_, "world");
    std::string meshUri;
    pnh_.getParam("mesh", meshUri);
    MeshLoadOptions options;
    pnh_.param("scale", options.scale, 1.0);
    pnh_.param("normalize", options.normalize, false);
    mesh_ = loadMesh(resolveMeshPath(meshUri), options);
    std::vector<double> tf;
    if (pnh_.getParam("mesh_in_pose_frame", tf) && tf.size() == 6) {
      // static_transform_publisher x y z yaw pitch roll: rotation = Rz(yaw) Ry(pitch) Rx(roll).
      meshToPose_ = Eigen::Translation3d(tf[0], tf[1], tf[2]) * Eigen::AngleAxisd(tf[3], Vec3::UnitZ()) *
                    Eigen::AngleAxisd(tf[4], Vec3::UnitY()) * Eigen::AngleAxisd(tf[5], Vec3::UnitX());
      // Debian has no static_transform_publisher binary: the test broadcasts the static transform itself.
      std::string meshFrame;
      pnh_.param<std::string>("mesh_frame", meshFrame, "mesh");
      geometry_msgs::TransformStamped t;
      t.header.stamp = ros::Time::now();
      t.header.frame_id = poseFrame_;
      t.child_frame_id = meshFrame;
      t.transform.translation.x = tf[0];
      t.transform.translation.y = tf[1];
      t.transform.translation.z = tf[2];
      const Eigen::Quaterniond q(meshToPose_.linear());
      t.transform.rotation.x = q.x();
      t.transform.rotation.y = q.y();
      t.transform.rotation.z = q.z();
      t.transform.rotation.w = q.w();
      staticBroadcaster_.sendTransform(t);
      transformToReach_ = true;
    }
    ros::NodeHandle dnh(ns_);
    dnh.param("pointer_radius", radius_, 0.002);
    dnh.param("stiffness", stiffness_, 500.0);
    proxyModel_ = dnh.param<std::string>("force_model", "proxy") == "proxy";
    posePub_ = nh_.advertise<geometry_msgs::PoseStamped>("/phantom/pose", 1000);
  }

  /**
   * Waits for the first level and the connections and, when the test broadcasts the mesh frame, until the
   * detector's tf2 buffer has that transform: the detector drops (and counts) a pose in a frame it cannot transform
   * yet, and /tf_static reaches it some time after the broadcaster advertises. Warm-up poses far from the mesh are
   * published until one is answered.
   */
  bool waitReady(double seconds = 60.0) {
    const bool ready = clod_haptics_test::waitUntil(
        [&] { return status().level_spheres > 0 && posePub_.getNumSubscribers() > 0 && answers_.connected(); }, seconds,
        0.02);
    if (!ready || !transformToReach_) return ready;
    const Vec3 farAway = meshToPose_ * (mesh_.modelBounds().max() + Vec3::Constant(10.0 * radius_));
    const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(seconds);
    while (ros::WallTime::now() < deadline) {
      Contact c;
      geometry_msgs::WrenchStamped f;
      if (waitAnswer(publish(farAway), c, f, 0.5)) {
        transformToReach_ = false;
        return true;
      }
    }
    return false;
  }

  /** Publishes a pose (position in the pose frame) with a fresh unique stamp; returns the stamp. */
  ros::Time publish(const Vec3& positionInPoseFrame, const std::string& frame = "", double nanValue = 0.0) {
    geometry_msgs::PoseStamped pose;
    pose.header.frame_id = frame.empty() ? poseFrame_ : frame;
    pose.header.stamp = nextStamp();
    pose.pose.position.x = positionInPoseFrame.x() + nanValue;
    pose.pose.position.y = positionInPoseFrame.y();
    pose.pose.position.z = positionInPoseFrame.z();
    pose.pose.orientation.w = 1.0;
    posePub_.publish(pose);
    return pose.header.stamp;
  }

  /** Waits for the contact and the force of a stamp. */
  bool waitAnswer(const ros::Time& stamp, Contact& contact, geometry_msgs::WrenchStamped& force, double seconds = 5.0) {
    return answers_.waitAnswer(stamp, contact, force, seconds);
  }

  bool answered(const ros::Time& stamp) { return answers_.hasContact(stamp); }
  std::map<ros::Time, Contact> contacts() { return answers_.contacts(); }
  DetectorStatus status() { return answers_.status(); }
  /** Waits until pred(status) holds. */
  template <class Pred>
  bool waitStatus(Pred pred, double seconds = 10.0) {
    return clod_haptics_test::waitUntil([&] { return pred(status()); }, seconds, 0.01);
  }

  /** Sets the detector's clustering distance through dynamic_reconfigure. */
  bool setClusteringDistance(double d) { return reconfigure({{"clustering_distance", d}}, {}); }

  /** Sets doubles and strings of the detector's dynamic_reconfigure in one call. */
  bool reconfigure(const std::map<std::string, double>& doubles, const std::map<std::string, std::string>& strings) {
    dynamic_reconfigure::Reconfigure srv = clod_haptics_test::reconfigureRequest(doubles, strings);
    return ros::service::call(ns_ + "/set_parameters", srv);
  }

  /** Points in the mesh frame: near the surface (both sides, within 2 r) and some far away. */
  std::vector<Vec3> probes(std::size_t nearCount, std::size_t farCount, std::uint64_t seed) const {
    std::vector<Vec3> points = nearSurfaceProbes(mesh_, nearCount, 2.0 * radius_, seed);
    const std::vector<Vec3> far = uniformProbes(mesh_, farCount, 4.0 * radius_, seed + 1);
    points.insert(points.end(), far.begin(), far.end());
    return points;
  }

  /**
   * Checks a contact and force against the brute-force reference for a probe given in the mesh frame. The force:
   * penalty, stiffness * depth along the normal; proxy, the spring to the proxy, which is never inside the mesh.
   */
  void expectMatchesReference(const Vec3& pMesh, const Contact& c, const geometry_msgs::WrenchStamped& f) const {
    const ContactResult ref = clod_haptics_test::streamReference(mesh_, pMesh, radius_, c.in_contact && c.inside);
    EXPECT_EQ(c.inside, ref.contact && ref.inside) << "probe " << pMesh.transpose();
    const double tol = 1e-9 * std::max(1.0, mesh_.diagonal());
    EXPECT_EQ(c.in_contact, ref.contact) << "probe " << pMesh.transpose() << " ref distance " << ref.distance;
    EXPECT_NEAR(c.pointer.x, pMesh.x(), 1e-9);
    EXPECT_NEAR(c.pointer.y, pMesh.y(), 1e-9);
    EXPECT_NEAR(c.pointer.z, pMesh.z(), 1e-9);
    const Vec3 forcePose(f.wrench.force.x, f.wrench.force.y, f.wrench.force.z);
    if (c.in_contact && ref.contact) {
      EXPECT_NEAR(c.distance, ref.distance, tol);
      EXPECT_NEAR(c.depth, ref.depth, tol);
      const Vec3 point(c.point.x, c.point.y, c.point.z);
      EXPECT_LT((point - ref.point).norm(), 1e-7 * std::max(1.0, mesh_.diagonal())) << "probe " << pMesh.transpose();
      const Vec3 normal(c.normal.x, c.normal.y, c.normal.z);
      EXPECT_NEAR(normal.norm(), 1.0, 1e-9);
      EXPECT_GT(c.triangle, -1);
    }
    if (!proxyModel_) {
      EXPECT_FALSE(c.proxy_active);
    }
    if (proxyModel_ && !c.proxy_active) {
      // The proxy waits to start until the pointer touches nothing and is not inside: a touching or inside
      // pointer (brute force with no radius bound) is the only reason to answer with the penalty force.
      const ContactResult deep = bruteForceSignedQuery(mesh_, pMesh, radius_);
      EXPECT_TRUE(ref.contact || (deep.contact && deep.inside))
          << "penalty force for a free pointer outside the mesh: " << pMesh.transpose();
    }
    if (proxyModel_ && c.proxy_active) {
      const Vec3 proxy(c.proxy.x, c.proxy.y, c.proxy.z);
      EXPECT_FALSE(bruteForceQuery(mesh_, proxy, radius_ * (1.0 - 1e-6)).contact)
          << "proxy inside: " << proxy.transpose();
      const Vec3 expected = meshToPose_.linear() * (stiffness_ * (proxy - pMesh));
      EXPECT_LT((forcePose - expected).norm(), 1e-9 * std::max(1.0, expected.norm()));
    } else if (c.in_contact && ref.contact) {
      // Force: stiffness * depth along the normal, expressed in the pose frame.
      const Vec3 normal(c.normal.x, c.normal.y, c.normal.z);
      const Vec3 expected = meshToPose_.linear() * (stiffness_ * c.depth * normal);
      EXPECT_LT((forcePose - expected).norm(), 1e-9 * std::max(1.0, expected.norm()));
    } else {
      EXPECT_EQ(forcePose.norm(), 0.0);
    }
    EXPECT_EQ(f.header.frame_id, poseFrame_);
  }

  const TriangleMesh& mesh() const { return mesh_; }
  const Eigen::Isometry3d& meshToPose() const { return meshToPose_; }
  double radius() const { return radius_; }
  bool proxyModel() const { return proxyModel_; }
  const std::string& ns() const { return ns_; }

 private:
  ros::Time nextStamp() {
    std::lock_guard<std::mutex> lock(mutex_);
    stampCounter_ += 1;
    return ros::Time(100, 0) + ros::Duration(0, static_cast<std::int32_t>(stampCounter_ % 1000000) * 1000) +
           ros::Duration(static_cast<double>(stampCounter_ / 1000000));
  }

  ros::NodeHandle nh_;
  ros::NodeHandle pnh_;
  std::string ns_;
  clod_haptics_test::DetectorAnswers answers_;
  std::string poseFrame_;
  TriangleMesh mesh_;
  Eigen::Isometry3d meshToPose_ = Eigen::Isometry3d::Identity();
  double radius_ = 0.002;
  double stiffness_ = 500.0;
  bool proxyModel_ = true;         // the detector's force_model
  bool transformToReach_ = false;  // the mesh frame is broadcast and no pose in the pose frame was answered yet
  tf2_ros::StaticTransformBroadcaster staticBroadcaster_;
  ros::Publisher posePub_;
  std::mutex mutex_;  // the stamp counter
  std::uint64_t stampCounter_ = 0;
};

DetectorClient& client() {
  static DetectorClient c;
  return c;
}

TEST(Detector, PosesInContactsOutMatchBruteForce) {
  DetectorClient& dc = client();
  ASSERT_TRUE(dc.waitReady()) << "no level or no connection from " << dc.ns();
  {  // The stylus comes from free space: the proxy model starts its proxy at a pose that touches nothing.
    const ros::Time stamp =
        dc.publish(dc.meshToPose() * (dc.mesh().modelBounds().max() + Vec3::Constant(10.0 * dc.radius())));
    Contact c;
    geometry_msgs::WrenchStamped f;
    ASSERT_TRUE(dc.waitAnswer(stamp, c, f));
    EXPECT_FALSE(c.in_contact);
  }
  const auto points = dc.probes(240, 60, 11);
  std::size_t touching = 0, free = 0;
  for (const Vec3& pMesh : points) {
    const ros::Time stamp = dc.publish(dc.meshToPose() * pMesh);
    Contact c;
    geometry_msgs::WrenchStamped f;
    ASSERT_TRUE(dc.waitAnswer(stamp, c, f)) << "pose unanswered: " << pMesh.transpose();
    dc.expectMatchesReference(pMesh, c, f);
    (c.in_contact ? touching : free) += 1;
    EXPECT_GT(c.level_spheres, 0u);
  }
  // Where the level came from: "service" (sphere_builder) or "local" (no service, or a set that does
  // not fit this detector's mesh).
  std::string source;
  if (ros::NodeHandle("~").getParam("expect_level_source", source)) {
    EXPECT_EQ(dc.status().level_source, source);
  }
  // The probe set must exercise both answers, or the test proves little.
  EXPECT_GT(touching, points.size() / 5);
  EXPECT_GT(free, points.size() / 5);
}

TEST(Detector, NanPoseAndUnknownFrameAreDroppedCountedAndTheDetectorKeepsRunning) {
  DetectorClient& dc = client();
  ASSERT_TRUE(dc.waitReady());
  const DetectorStatus before = dc.status();
  const Vec3 pMesh = dc.probes(1, 0, 5)[0];
  const ros::Time nanStamp = dc.publish(dc.meshToPose() * pMesh, "", std::numeric_limits<double>::quiet_NaN());
  const ros::Time infStamp = dc.publish(dc.meshToPose() * pMesh, "", std::numeric_limits<double>::infinity());
  const ros::Time badFrameStamp = dc.publish(dc.meshToPose() * pMesh, "no_such_frame");
  const ros::Time goodStamp = dc.publish(dc.meshToPose() * pMesh);
  Contact c;
  geometry_msgs::WrenchStamped f;
  ASSERT_TRUE(dc.waitAnswer(goodStamp, c, f)) << "a good pose after bad ones went unanswered";
  dc.expectMatchesReference(pMesh, c, f);
  EXPECT_FALSE(dc.answered(nanStamp));
  EXPECT_FALSE(dc.answered(infStamp));
  EXPECT_FALSE(dc.answered(badFrameStamp));
  EXPECT_TRUE(dc.waitStatus([&](const DetectorStatus& s) {
    return s.dropped_non_finite >= before.dropped_non_finite + 2 &&
           s.dropped_unknown_frame >= before.dropped_unknown_frame + 1;
  })) << "the drops were not counted in "
      << dc.ns() << "/status";
}

TEST(Detector, ReconfigureDuringAStreamChangesTheLevelAndAnswersEveryPose) {
  DetectorClient& dc = client();
  ASSERT_TRUE(dc.waitReady());
  double d0 = 0.0, d1 = 0.0;
  ros::NodeHandle("~").param("reconfigure_from", d0, 0.003);
  ros::NodeHandle("~").param("reconfigure_to", d1, 0.0);
  ASSERT_TRUE(dc.setClusteringDistance(d0));
  ASSERT_TRUE(dc.waitStatus([&](const DetectorStatus& s) { return s.clustering_distance == d0; }, 60.0));
  const std::uint32_t spheres0 = dc.status().level_spheres;

  const auto points = dc.probes(800, 200, 23);
  std::vector<std::pair<ros::Time, Vec3>> sent;
  std::atomic<bool> streaming{true};
  std::thread stream([&] {
    ros::WallRate rate(500.0);
    for (std::size_t k = 0; streaming || k < 500; ++k) {
      const Vec3& pMesh = points[k % points.size()];
      sent.emplace_back(dc.publish(dc.meshToPose() * pMesh), pMesh);
      rate.sleep();
      if (k > 20000) break;
    }
  });
  ros::WallDuration(0.3).sleep();
  ASSERT_TRUE(dc.setClusteringDistance(d1));
  const bool swapped = dc.waitStatus([&](const DetectorStatus& s) { return s.clustering_distance == d1; }, 60.0);
  ros::WallDuration(0.3).sleep();
  streaming = false;
  stream.join();
  ASSERT_TRUE(swapped) << "the level for d = " << d1 << " never arrived";
  const std::uint32_t spheres1 = dc.status().level_spheres;
  EXPECT_NE(spheres0, spheres1) << "d " << d0 << " -> " << d1 << " should change the sphere count";

  // Every pose answered (allow the last ones a moment), each correct, and both levels seen.
  ros::WallDuration(0.5).sleep();
  Contact c;
  geometry_msgs::WrenchStamped f;
  std::set<std::uint32_t> levelsSeen;
  std::size_t unanswered = 0;
  for (const auto& s : sent) {
    if (!dc.waitAnswer(s.first, c, f, 2.0)) {
      ++unanswered;
      continue;
    }
    dc.expectMatchesReference(s.second, c, f);
    levelsSeen.insert(c.level_spheres);
  }
  EXPECT_EQ(unanswered, 0u) << "of " << sent.size() << " poses";
  EXPECT_GT(sent.size(), 300u);
  EXPECT_TRUE(levelsSeen.count(spheres0)) << "no pose answered by the first level";
  EXPECT_TRUE(levelsSeen.count(spheres1)) << "no pose answered by the new level";
}

// A level swap frees the old level while the pose stream's QueryCache still remembers a cell of it, and the
// next level is often allocated at the same address. Two swaps with no pose in between, six times over (the
// manager died within six such cycles when the cache recognised its detector by address): every answer after
// them against brute force, and the detector still answering at the end.
TEST(Detector, TwoReconfiguresWithoutAPoseBetweenThenEveryAnswerMatchesBruteForce) {
  DetectorClient& dc = client();
  ASSERT_TRUE(dc.waitReady());
  const std::vector<double> distances = {0.0, 0.004, 0.002, 0.006};
  const auto points = dc.probes(120, 30, 57);
  std::size_t checked = 0, next = 0;
  auto sendAndCheck = [&](std::size_t count) {
    std::vector<std::pair<ros::Time, Vec3>> sent;
    for (std::size_t k = 0; k < count; ++k, ++next) {
      const Vec3& pMesh = points[next % points.size()];
      sent.emplace_back(dc.publish(dc.meshToPose() * pMesh), pMesh);
      ros::WallDuration(0.001).sleep();
    }
    Contact c;
    geometry_msgs::WrenchStamped f;
    for (const auto& s : sent) {
      ASSERT_TRUE(dc.waitAnswer(s.first, c, f, 5.0)) << "a pose after the swaps was not answered";
      dc.expectMatchesReference(s.second, c, f);
      ++checked;
    }
  };
  sendAndCheck(40);  // the cache now holds a cell of the current level
  for (int cycle = 0; cycle < 6; ++cycle) {
    for (int swap = 0; swap < 2; ++swap) {
      const double d = distances[(2 * cycle + swap) % distances.size()];
      ASSERT_TRUE(dc.setClusteringDistance(d));
      ASSERT_TRUE(dc.waitStatus([&](const DetectorStatus& st) { return st.clustering_distance == d; }, 60.0))
          << "cycle " << cycle << ": the level for d = " << d << " never arrived";
    }
    // The first pose after the swaps is the last one before them: the cell the stale cache entry names.
    next -= 1;
    sendAndCheck(40);
  }
  EXPECT_EQ(checked, 40u * 7u);
  const std::uint64_t before = dc.status().sequence;
  EXPECT_TRUE(dc.waitStatus([&](const DetectorStatus& st) { return st.sequence > before; }, 5.0))
      << "no status heartbeat after the swaps";
}

// A burst of poses faster than the detector answers them: every pose is answered or, under pose_policy latest,
// counted as skipped; none disappears. Under latest the newest pose of the burst is always answered.
TEST(Detector, ABurstOfPosesIsAnsweredOrCountedNeverLostSilently) {
  DetectorClient& dc = client();
  ASSERT_TRUE(dc.waitReady());
  // A status from after the previous test's poses, as the baseline.
  const std::uint64_t seq0 = dc.status().sequence;
  ASSERT_TRUE(dc.waitStatus([&](const DetectorStatus& st) { return st.sequence > seq0; }, 5.0));
  const DetectorStatus before = dc.status();
  const auto points = dc.probes(200, 50, 77);
  const std::size_t n = 800;  // under the test publisher's queue of 1000: the burst leaves this process whole
  std::vector<std::pair<ros::Time, Vec3>> sent;
  for (std::size_t k = 0; k < n; ++k) {
    const Vec3& pMesh = points[k % points.size()];
    sent.emplace_back(dc.publish(dc.meshToPose() * pMesh), pMesh);  // no pause: a backlog forms
  }
  ASSERT_TRUE(
      dc.waitStatus([&](const DetectorStatus& st) { return st.poses_received >= before.poses_received + n; }, 30.0))
      << "the detector did not receive the burst";
  const std::uint64_t seq1 = dc.status().sequence;
  ASSERT_TRUE(dc.waitStatus([&](const DetectorStatus& st) { return st.sequence > seq1; }, 5.0));
  const DetectorStatus after = dc.status();
  const std::uint64_t received = after.poses_received - before.poses_received;
  const std::uint64_t answered = after.contacts_published - before.contacts_published;
  const std::uint64_t skipped = after.poses_skipped_stale - before.poses_skipped_stale;
  EXPECT_EQ(received, n);
  EXPECT_EQ(answered + skipped, received) << "answered " << answered << ", skipped " << skipped;
  std::size_t heard = 0;
  Contact c;
  geometry_msgs::WrenchStamped f;
  for (const auto& s : sent) {
    if (!dc.answered(s.first)) continue;
    ASSERT_TRUE(dc.waitAnswer(s.first, c, f, 1.0));
    dc.expectMatchesReference(s.second, c, f);
    ++heard;
  }
  EXPECT_EQ(heard, answered);
  EXPECT_TRUE(dc.answered(sent.back().first)) << "the newest pose of the burst was not answered";
  if (after.pose_policy == "all") {
    EXPECT_EQ(skipped, 0u);
    EXPECT_EQ(answered, n);
  } else {
    ASSERT_EQ(after.pose_policy, "latest");
    std::printf("pose_policy latest: %lu of %zu poses of the burst skipped as stale\n",
                static_cast<unsigned long>(skipped), n);
  }
}

// The status is a heartbeat a watchdog can use, and says how poses are handled and what was lost.
TEST(Detector, StatusIsAHeartbeatWithLossCountersAndThePosePath) {
  DetectorClient& dc = client();
  ASSERT_TRUE(dc.waitReady());
  const ros::Time stamp = dc.publish(dc.meshToPose() * dc.probes(1, 0, 3).front());
  Contact c;
  geometry_msgs::WrenchStamped f;
  ASSERT_TRUE(dc.waitAnswer(stamp, c, f));
  const DetectorStatus first = dc.status();
  ASSERT_TRUE(dc.waitStatus([&](const DetectorStatus& st) { return st.sequence >= first.sequence + 2; }, 5.0))
      << "the status stopped beating";
  const DetectorStatus s = dc.status();
  EXPECT_GE((s.header.stamp - first.header.stamp).toSec(), 0.5);
  EXPECT_TRUE(s.pose_policy == "all" || s.pose_policy == "latest") << s.pose_policy;
  EXPECT_GE(s.pose_queue_size, 1u);
  EXPECT_GE(s.publish_queue_size, 1u);
  // The test's poses carry no header.seq (roscpp leaves it 0): nothing can be counted lost from them.
  EXPECT_EQ(s.poses_lost_upstream, 0u);
  EXPECT_GT(s.pose_path_max_us, 0.0);
  EXPECT_LE(s.pose_path_p50_us, s.pose_path_p999_us);
  EXPECT_LE(s.pose_path_p999_us, s.pose_path_max_us);
  // Answers are numbered consecutively for their subscribers.
  EXPECT_GT(c.header.seq, 0u);
  EXPECT_LE(c.header.seq, s.contacts_published);
  EXPECT_EQ(f.header.seq, c.header.seq);
}

TEST(Detector, DetectionModeAndPointerRadiusFollowReconfigure) {
  DetectorClient& dc = client();
  ASSERT_TRUE(dc.waitReady());
  // The reference: the core detector on the same level (sphere_builder and a local build agree).
  const double d = dc.status().clustering_distance;
  auto mesh = std::make_shared<const TriangleMesh>(dc.mesh());
  auto set = std::make_shared<const ClodSphereSet>(ClodBuilder(mesh).build(d));
  std::string fastName;
  ros::NodeHandle(dc.ns()).param<std::string>("fast_level", fastName, "grid");
  FastLevel fast;
  ASSERT_TRUE(parseFastLevel(fastName.c_str(), fast));
  double gridRadius = 0.0;
  ros::NodeHandle(dc.ns()).param("grid_radius", gridRadius, 0.0);
  const ClodDetector reference(mesh, set, fast, gridRadius);
  const double r = 1.5 * dc.radius();
  const auto points = dc.probes(150, 30, 41);
  for (const char* name : {"spheres", "paper", "exact"}) {
    DetectionMode mode;
    ASSERT_TRUE(parseDetectionMode(name, mode));
    // The reconfigure callback stores the settings before it answers: every pose sent after it uses them.
    ASSERT_TRUE(dc.reconfigure({{"pointer_radius", r}}, {{"detection_mode", name}}));
    // The reference answers the same stream as the node (a QueryCache: a stream pushed into the part follows
    // it deeper than r). A pose far outside first ends any penetration the node's stream still follows.
    QueryCache stream;
    const Vec3 far = dc.mesh().modelBounds().max() + Vec3::Constant(10.0 * dc.mesh().diagonal());
    {
      Contact c;
      geometry_msgs::WrenchStamped f;
      ASSERT_TRUE(dc.waitAnswer(dc.publish(dc.meshToPose() * far), c, f));
      ContactResult none;
      reference.query(far, r, mode, none, &stream);
      ASSERT_FALSE(c.in_contact || none.contact);
    }
    std::size_t touching = 0;
    for (const Vec3& p : points) {
      Contact c;
      geometry_msgs::WrenchStamped f;
      ASSERT_TRUE(dc.waitAnswer(dc.publish(dc.meshToPose() * p), c, f));
      EXPECT_DOUBLE_EQ(c.pointer_radius, r);
      EXPECT_DOUBLE_EQ(c.clustering_distance, d);
      ASSERT_EQ(c.level_spheres, set->size());
      ContactResult expected;
      reference.query(p, r, mode, expected, &stream);
      EXPECT_EQ(c.in_contact, expected.contact) << name << " probe " << p.transpose();
      if (c.in_contact && expected.contact) {
        EXPECT_NEAR(c.distance, expected.distance, 1e-9) << name;
        EXPECT_NEAR(c.depth, expected.depth, 1e-9) << name;
        // The same coordinates give the same triangle; through tf2 they differ in the last bits, and an
        // edge shared by two triangles may then go to either.
        if (dc.meshToPose().matrix() == Eigen::Matrix4d::Identity()) {
          EXPECT_EQ(c.triangle, expected.triangle) << name;
        }
        ++touching;
      }
    }
    EXPECT_GT(touching, points.size() / 5) << name;
  }
  // With fast_level grid and grid_radius 0 the grids follow the pointer radius: rebuilt off the haptic path
  // (the answers above came meanwhile from the old grid and its hierarchy), then in use.
  const bool follows = fast == FastLevel::Grid && gridRadius == 0.0;
  if (follows) {
    EXPECT_TRUE(dc.waitStatus([&](const DetectorStatus& s) { return s.grid_radius == r; }, 60.0))
        << "grid radius " << dc.status().grid_radius << ", pointer radius " << r;
  }
  ASSERT_TRUE(dc.reconfigure({{"pointer_radius", dc.radius()}}, {{"detection_mode", "exact"}}));
  if (follows) {
    EXPECT_TRUE(dc.waitStatus([&](const DetectorStatus& s) { return s.grid_radius == dc.radius(); }, 60.0))
        << "grid radius " << dc.status().grid_radius << ", pointer radius " << dc.radius();
  }
}

/** The markers as RViz would hold them: ADD replaces (ns, id), DELETE removes it. */
class MarkerScene {
 public:
  explicit MarkerScene(const std::string& topic) {
    sub_ = ros::NodeHandle().subscribe(topic, 100, &MarkerScene::onArray, this);
  }
  std::map<std::pair<std::string, int>, visualization_msgs::Marker> markers() {
    std::lock_guard<std::mutex> lock(mutex_);
    return markers_;
  }
  std::size_t count(const std::string& ns) {
    std::size_t n = 0;
    for (const auto& m : markers()) n += m.first.first == ns ? 1 : 0;
    return n;
  }
  std::size_t arrays() {
    std::lock_guard<std::mutex> lock(mutex_);
    return arrays_;
  }
  /** Points of the list markers in namespace ns: the spheres drawn there. */
  std::size_t points(const std::string& ns) {
    std::size_t n = 0;
    for (const auto& m : markers()) n += m.first.first == ns ? m.second.points.size() : 0;
    return n;
  }

 private:
  void onArray(const visualization_msgs::MarkerArrayConstPtr& array) {
    std::lock_guard<std::mutex> lock(mutex_);
    ++arrays_;
    for (const auto& m : array->markers) {
      if (m.action == visualization_msgs::Marker::DELETE) {
        markers_.erase({m.ns, m.id});
      } else {
        markers_[{m.ns, m.id}] = m;
      }
    }
  }
  ros::Subscriber sub_;
  std::mutex mutex_;
  std::map<std::pair<std::string, int>, visualization_msgs::Marker> markers_;
  std::size_t arrays_ = 0;
};

std::pair<std::string, int> key(const std::string& ns) { return {ns, 0}; }

// With force_model proxy, ~proxy carries the proxy of each answer (the Contact's proxy field), and a pose pushed
// through the surface leaves the proxy outside on the side it came from.
TEST(Detector, ProxyPoseIsPublishedBesideTheContact) {
  DetectorClient& dc = client();
  if (!dc.proxyModel()) GTEST_SKIP() << "force_model penalty";
  ASSERT_TRUE(dc.waitReady());
  std::mutex mutex;
  std::map<ros::Time, geometry_msgs::PoseStamped> proxies;
  ros::NodeHandle nh;
  ros::Subscriber sub = nh.subscribe<geometry_msgs::PoseStamped>(dc.ns() + "/proxy", 100,
                                                                 [&](const geometry_msgs::PoseStamped::ConstPtr& msg) {
                                                                   std::lock_guard<std::mutex> lock(mutex);
                                                                   proxies[msg->header.stamp] = *msg;
                                                                 });
  ASSERT_TRUE(clod_haptics_test::waitUntil([&] { return sub.getNumPublishers() > 0; }, 10.0, 0.01));
  // From free space straight into the mesh: the nearest surface point of a point far outside, then 1.5 r past it.
  const Vec3 outside = dc.mesh().modelBounds().max() + Vec3::Constant(10.0 * dc.radius());
  const ContactResult near = bruteForceQuery(dc.mesh(), outside, 1e9);
  const Vec3 in = near.point - near.normal * 1.5 * dc.radius();
  for (int i = -10; i <= 20; ++i) {  // ten poses outside first: the proxy comes round from wherever it was
    const Vec3 pMesh = outside + (in - outside) * (std::max(i, 0) / 20.0);
    const ros::Time stamp = dc.publish(dc.meshToPose() * pMesh);
    Contact c;
    geometry_msgs::WrenchStamped f;
    ASSERT_TRUE(dc.waitAnswer(stamp, c, f));
    ASSERT_TRUE(clod_haptics_test::waitUntil(
        [&] {
          std::lock_guard<std::mutex> lock(mutex);
          return proxies.count(stamp) > 0;
        },
        5.0, 0.001));
    std::lock_guard<std::mutex> lock(mutex);
    const geometry_msgs::Point& q = proxies[stamp].pose.position;
    EXPECT_EQ(q.x, c.proxy.x);
    EXPECT_EQ(q.y, c.proxy.y);
    EXPECT_EQ(q.z, c.proxy.z);
    dc.expectMatchesReference(pMesh, c, f);
    EXPECT_TRUE(c.proxy_active) << "pose " << i << ": the proxy started at the first free pose outside";
    if (i == 20) {  // the pointer is 1.5 r inside; the proxy rests on the surface, r out along the normal
      const Vec3 proxy(q.x, q.y, q.z);
      EXPECT_LT((proxy - (near.point + near.normal * dc.radius())).norm(), 1e-6 * dc.radius());
    }
  }
}

// A proxy that (re)starts must not start inside a closed mesh, where its sweeps would keep it trapped behind the
// surface: after a reset (a pointer radius change) the first poses lie deep inside, farther than r from any
// triangle; they are answered by the penalty force (proxy_active false), and the proxy starts at the first pose
// outside. Then the path goes back in: the proxy stays outside, on the surface.
TEST(Detector, ProxyNeverStartsDeepInsideTheMesh) {
  DetectorClient& dc = client();
  if (!dc.proxyModel()) GTEST_SKIP() << "force_model penalty";
  ASSERT_TRUE(dc.waitReady());
  std::vector<Vec3> deep;
  for (const Vec3& p : uniformProbes(dc.mesh(), 4000, 0.0, 41)) {
    const ContactResult ref = bruteForceSignedQuery(dc.mesh(), p, dc.radius());
    if (ref.contact && ref.inside && ref.distance > 2.0 * dc.radius()) deep.push_back(p);
    if (deep.size() == 5) break;
  }
  if (deep.empty()) GTEST_SKIP() << "no point deeper than 2 r inside this mesh";
  // A radius change resets the proxy; the old radius comes back for the tests after this one.
  const Vec3 outside = dc.mesh().modelBounds().max() + Vec3::Constant(10.0 * dc.radius());
  Contact c;
  geometry_msgs::WrenchStamped f;
  ASSERT_TRUE(dc.reconfigure({{"pointer_radius", 1.25 * dc.radius()}}, {}));
  ASSERT_TRUE(dc.waitAnswer(dc.publish(dc.meshToPose() * outside), c, f));  // the proxy runs at 1.25 r
  ASSERT_TRUE(dc.reconfigure({{"pointer_radius", dc.radius()}}, {}));
  for (const Vec3& p : deep) {
    ASSERT_TRUE(dc.waitAnswer(dc.publish(dc.meshToPose() * p), c, f));
    EXPECT_FALSE(c.proxy_active) << "the proxy started inside at " << p.transpose();
    dc.expectMatchesReference(p, c, f);
  }
  ASSERT_TRUE(dc.waitAnswer(dc.publish(dc.meshToPose() * outside), c, f));
  EXPECT_TRUE(c.proxy_active) << "the proxy did not start at a free pose";
  for (int i = 1; i <= 10; ++i) {  // straight back to the first deep point
    const Vec3 p = outside + (deep.front() - outside) * (i / 10.0);
    ASSERT_TRUE(dc.waitAnswer(dc.publish(dc.meshToPose() * p), c, f));
    EXPECT_TRUE(c.proxy_active);
    dc.expectMatchesReference(p, c, f);  // the proxy is never inside
  }
}

TEST(Detector, MarkersShowTheMeshTheLevelTheHitSpheresAndTheContact) {
  DetectorClient& dc = client();
  ASSERT_TRUE(dc.waitReady());
  // The level's spheres and the spheres hit are off by default (config/detector.yaml): shown here.
  dynamic_reconfigure::Reconfigure show;
  for (const char* name : {"show_spheres", "show_hit_spheres"}) {
    dynamic_reconfigure::BoolParameter b;
    b.name = name;
    b.value = true;
    show.request.config.bools.push_back(b);
  }
  ASSERT_TRUE(ros::service::call(dc.ns() + "/set_parameters", show));
  MarkerScene scene(dc.ns() + "/markers");
  // A touching probe, held for a while as a stylus would be.
  Vec3 touching = Vec3::Zero();
  for (const Vec3& p : dc.probes(50, 0, 31)) {
    if (bruteForceQuery(dc.mesh(), p, dc.radius()).contact) {
      touching = p;
      break;
    }
  }
  const ContactResult ref = bruteForceQuery(dc.mesh(), touching, dc.radius());
  ASSERT_TRUE(ref.contact);
  auto hold = [&](const Vec3& p, double seconds) {
    const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(seconds);
    Contact c;
    geometry_msgs::WrenchStamped f;
    while (ros::WallTime::now() < end) {
      ASSERT_TRUE(dc.waitAnswer(dc.publish(dc.meshToPose() * p), c, f));
      ros::WallDuration(0.01).sleep();
    }
  };
  hold(touching, 1.5);
  const std::size_t arrays = scene.arrays();
  EXPECT_GT(arrays, 10u) << "markers should flow at about 30 Hz while subscribed";
  EXPECT_LT(arrays, 100u) << "markers must come at display rate, not once per pose";

  auto markers = scene.markers();
  ASSERT_TRUE(markers.count(key("mesh")));
  EXPECT_EQ(markers[key("mesh")].points.size(), 3 * dc.mesh().size());
  EXPECT_EQ(scene.points("spheres"), dc.status().level_spheres);
  EXPECT_GE(scene.points("hit_spheres"), 1u);
  ASSERT_TRUE(markers.count(key("contact_point")));
  ASSERT_TRUE(markers.count(key("contact_normal")));
  ASSERT_TRUE(markers.count(key("pointer")));
  const auto& point = markers[key("contact_point")].pose.position;
  EXPECT_LT((Vec3(point.x, point.y, point.z) - ref.point).norm(), 1e-7);
  const auto& pointer = markers[key("pointer")].pose.position;
  EXPECT_LT((Vec3(pointer.x, pointer.y, pointer.z) - touching).norm(), 1e-9);
  EXPECT_NEAR(markers[key("pointer")].scale.x, 2.0 * dc.radius(), 1e-12);

  // Moving away clears the contact markers and the highlighted spheres.
  Vec3 away = dc.mesh().modelBounds().max() + Vec3::Constant(10.0 * dc.radius());
  hold(away, 0.6);
  markers = scene.markers();
  EXPECT_FALSE(markers.count(key("contact_point")));
  EXPECT_FALSE(markers.count(key("contact_normal")));
  EXPECT_EQ(scene.count("hit_spheres"), 0u);
  ASSERT_TRUE(markers.count(key("pointer")));
  EXPECT_NEAR(markers[key("pointer")].pose.position.x, away.x(), 1e-9);
}

}  // namespace
}  // namespace clod_haptics

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_detector");
  ros::AsyncSpinner spinner(2);
  spinner.start();
  const int result = RUN_ALL_TESTS();
  spinner.stop();
  ros::shutdown();
  return result;
}
