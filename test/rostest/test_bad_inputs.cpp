// rostest: bad input into the running nodes. Each bad input gets a clear answer (dropped and
// counted, clamped, refused with a message, or a clean non-zero exit for a broken mesh file), the nodes
// stay up, and the next valid input is answered correctly: contacts against the core's brute-force
// reference on the same mesh, sphere sets against the core's builder.
// Runs against bad_inputs.test: sphere_builder and the detector nodelet on the bundled torus.
#include <dynamic_reconfigure/Config.h>
#include <dynamic_reconfigure/Reconfigure.h>
#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/WrenchStamped.h>
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <sys/wait.h>
#include <tf2_ros/static_transform_broadcaster.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <mutex>
#include <string>
#include <vector>

#include "clod_haptics/Contact.h"
#include "clod_haptics/DetectorStatus.h"
#include "clod_haptics/GetSphereSet.h"
#include "clod_haptics/core/brute_force.h"
#include "clod_haptics/core/errors.h"
#include "clod_haptics/core/mesh_loader.h"
#include "clod_haptics/core/probes.h"
#include "clod_haptics/core/sphere_set.h"
#include "clod_haptics/test_config.h"
#include "detector_answers.h"
#include "run_command.h"

namespace clod_haptics {
namespace {

const double kNaN = std::numeric_limits<double>::quiet_NaN();
const double kInf = std::numeric_limits<double>::infinity();
const char* kDetector = "/detector";
const char* kService = "/sphere_builder/get_sphere_set";
const char* kTilted = "bad_inputs_tilted";  // a frame rotated 45 degrees about z from the mesh frame

/** One pose as sent: position and orientation (x, y, z, w) in a frame. */
struct Pose {
  Vec3 position = Vec3::Zero();
  std::array<double, 4> orientation{{0.0, 0.0, 0.0, 1.0}};
  std::string frame = "world";
};

class Rig {
 public:
  Rig() : answers_(kDetector) {
    MeshLoadOptions options;  // as the nodes load it: scale 1, not normalised
    std::string path;
    ros::NodeHandle("~").getParam("mesh", path);
    mesh_ = std::make_shared<const TriangleMesh>(loadMesh(path, options));
    builder_ = std::make_unique<ClodBuilder>(mesh_);
    posePub_ = nh_.advertise<geometry_msgs::PoseStamped>("/phantom/pose", 1000);
    geometry_msgs::TransformStamped t;
    t.header.stamp = ros::Time::now();
    t.header.frame_id = "world";
    t.child_frame_id = kTilted;
    t.transform.rotation.z = std::sin(M_PI / 8.0);
    t.transform.rotation.w = std::cos(M_PI / 8.0);
    broadcaster_.sendTransform(t);
    // Probes near the surface (both sides, within 4 mm) and a few away from it, fixed seed.
    probes_ = nearSurfaceProbes(*mesh_, 12, 0.004, 7);
    for (const Vec3& p : uniformProbes(*mesh_, 4, 0.01, 8)) probes_.push_back(p);
  }

  bool waitReady(double seconds = 60.0) {
    return waitFor(
        [&] { return status().level_spheres > 0 && posePub_.getNumSubscribers() > 0 && answers_.connected(); },
        seconds);
  }

  template <class Pred>
  static bool waitFor(Pred pred, double seconds) {
    return clod_haptics_test::waitUntil(pred, seconds);
  }

  ros::Time publish(const Pose& pose) {
    geometry_msgs::PoseStamped msg;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      ++counter_;
      msg.header.stamp = ros::Time(500, 0) + ros::Duration(0, static_cast<std::int32_t>(counter_ * 1000));
    }
    msg.header.frame_id = pose.frame;
    msg.pose.position.x = pose.position.x();
    msg.pose.position.y = pose.position.y();
    msg.pose.position.z = pose.position.z();
    msg.pose.orientation.x = pose.orientation[0];
    msg.pose.orientation.y = pose.orientation[1];
    msg.pose.orientation.z = pose.orientation[2];
    msg.pose.orientation.w = pose.orientation[3];
    posePub_.publish(msg);
    return msg.header.stamp;
  }

  bool waitAnswer(const ros::Time& stamp, Contact& c, geometry_msgs::WrenchStamped& f, double seconds = 5.0) {
    return answers_.waitAnswer(stamp, c, f, seconds);
  }

  bool answered(const ros::Time& stamp) { return answers_.hasContact(stamp) || answers_.hasForce(stamp); }

  DetectorStatus status() { return answers_.status(); }

  /** Sets doubles and strings through dynamic_reconfigure; returns the configuration the server applied. */
  bool reconfigure(const std::map<std::string, double>& doubles, const std::map<std::string, std::string>& strings,
                   dynamic_reconfigure::Config& applied) {
    dynamic_reconfigure::Reconfigure srv = clod_haptics_test::reconfigureRequest(doubles, strings);
    if (!ros::service::call(std::string(kDetector) + "/set_parameters", srv)) return false;
    applied = srv.response.config;
    return true;
  }

  static double value(const dynamic_reconfigure::Config& config, const std::string& name) {
    for (const auto& p : config.doubles)
      if (p.name == name) return p.value;
    return kNaN;
  }
  static std::string text(const dynamic_reconfigure::Config& config, const std::string& name) {
    for (const auto& p : config.strs)
      if (p.name == name) return p.value;
    return "";
  }

  /**
   * \brief The valid probes in the mesh frame, each answered and equal to the brute-force reference for
   * the radius in use; the force is stiffness * depth along the normal. Returns how many touched.
   */
  std::size_t expectValidPosesAnsweredCorrectly(double radius, double stiffness, const std::string& after) {
    std::size_t touching = 0;
    for (const Vec3& p : probes_) {
      Pose pose;
      pose.position = p;
      const ros::Time stamp = publish(pose);
      Contact c;
      geometry_msgs::WrenchStamped f;
      if (!waitAnswer(stamp, c, f)) {
        ADD_FAILURE() << "after " << after << ": a valid pose went unanswered";
        return touching;
      }
      const ContactResult ref = clod_haptics_test::streamReference(*mesh_, p, radius, c.in_contact && c.inside);
      EXPECT_EQ(c.pointer_radius, radius) << after;
      EXPECT_EQ(c.in_contact, ref.contact) << after << ": probe " << p.transpose() << " ref distance " << ref.distance;
      const Vec3 force(f.wrench.force.x, f.wrench.force.y, f.wrench.force.z);
      EXPECT_TRUE(force.allFinite()) << after;
      if (c.in_contact && ref.contact) {
        ++touching;
        EXPECT_NEAR(c.distance, ref.distance, 1e-9) << after;
        EXPECT_NEAR(c.depth, ref.depth, 1e-9) << after;
        EXPECT_LT((Vec3(c.point.x, c.point.y, c.point.z) - ref.point).norm(), 1e-7) << after;
        const Vec3 normal(c.normal.x, c.normal.y, c.normal.z);
        EXPECT_LT((force - stiffness * c.depth * normal).norm(), 1e-9 * std::max(1.0, stiffness)) << after;
      } else {
        EXPECT_EQ(force.norm(), 0.0) << after;
      }
    }
    return touching;
  }

  /** The nodes of bad_inputs.test are still registered with the master. */
  static void expectNodesUp(const std::string& after) {
    std::vector<std::string> nodes;
    ASSERT_TRUE(ros::master::getNodes(nodes));
    for (const char* name : {"/bad_inputs_manager", "/sphere_builder"}) {
      EXPECT_NE(std::find(nodes.begin(), nodes.end(), name), nodes.end()) << name << " is gone after " << after;
    }
  }

  std::size_t expectedSpheres(double d) const { return builder_->build(d).size(); }
  const TriangleMesh& mesh() const { return *mesh_; }
  const std::vector<Vec3>& probes() const { return probes_; }

 private:
  ros::NodeHandle nh_;
  std::shared_ptr<const TriangleMesh> mesh_;
  std::unique_ptr<ClodBuilder> builder_;
  std::vector<Vec3> probes_;
  tf2_ros::StaticTransformBroadcaster broadcaster_;
  ros::Publisher posePub_;
  clod_haptics_test::DetectorAnswers answers_;
  std::mutex mutex_;  // the stamp counter
  std::uint64_t counter_ = 0;
};

Rig& rig() {
  static Rig r;
  return r;
}

const double kRadius = 0.002;     // config/detector.yaml
const double kStiffness = 400.0;  // config/detector.yaml
const double kDistance = 0.003;   // config/detector.yaml

TEST(BadInputs, NonFinitePosesAreDroppedAndCounted) {
  Rig& r = rig();
  ASSERT_TRUE(r.waitReady());
  const Vec3 p = r.probes().front();
  struct Case {
    const char* name;
    Pose pose;
  };
  std::vector<Case> cases(6);
  cases[0].name = "NaN x";
  cases[0].pose.position = Vec3(kNaN, p.y(), p.z());
  cases[1].name = "Inf y";
  cases[1].pose.position = Vec3(p.x(), kInf, p.z());
  cases[2].name = "-Inf z";
  cases[2].pose.position = Vec3(p.x(), p.y(), -kInf);
  cases[3].name = "NaN orientation";
  cases[3].pose.position = p;
  cases[3].pose.orientation = {{0.0, 0.0, 0.0, kNaN}};
  cases[4].name = "Inf orientation";
  cases[4].pose.position = p;
  cases[4].pose.orientation = {{kInf, 0.0, 0.0, 1.0}};
  // Finite in its own frame, Inf once rotated into the mesh frame (the y component overflows).
  cases[5].name = "1.7e308 rotated into the mesh frame";
  cases[5].pose.position = Vec3(1.7e308, 1.7e308, 0.0);
  cases[5].pose.frame = kTilted;
  // The tilted frame is known before the overflow case is sent (else it would count as an unknown frame).
  Pose probeTilted;
  probeTilted.frame = kTilted;
  ASSERT_TRUE(Rig::waitFor(
      [&] {
        Contact c;
        geometry_msgs::WrenchStamped f;
        return r.waitAnswer(r.publish(probeTilted), c, f, 0.2);
      },
      10.0))
      << "the test's static transform never reached the detector";

  for (const Case& k : cases) {
    const DetectorStatus before = r.status();
    const ros::Time bad = r.publish(k.pose);
    r.expectValidPosesAnsweredCorrectly(kRadius, kStiffness, k.name);
    EXPECT_FALSE(r.answered(bad)) << k.name << " was answered";
    EXPECT_TRUE(Rig::waitFor([&] { return r.status().dropped_non_finite == before.dropped_non_finite + 1; }, 5.0))
        << k.name << ": not counted in ~status dropped_non_finite";
    Rig::expectNodesUp(k.name);
  }
}

TEST(BadInputs, HugeFinitePosesAreAnsweredWithoutContactOrForce) {
  Rig& r = rig();
  ASSERT_TRUE(r.waitReady());
  for (const Vec3& huge :
       {Vec3(1e300, 0.0, 0.0), Vec3(-1e300, 1e300, 1e300), Vec3(0.0, 0.0, -1e300), Vec3(1.7e308, -1.7e308, 1.7e308)}) {
    Pose pose;
    pose.position = huge;
    Contact c;
    geometry_msgs::WrenchStamped f;
    ASSERT_TRUE(r.waitAnswer(r.publish(pose), c, f)) << huge.transpose();
    EXPECT_FALSE(bruteForceQuery(r.mesh(), huge, kRadius).contact);
    EXPECT_FALSE(c.in_contact) << huge.transpose();
    EXPECT_EQ(f.wrench.force.x, 0.0);
    EXPECT_EQ(f.wrench.force.y, 0.0);
    EXPECT_EQ(f.wrench.force.z, 0.0);
    EXPECT_EQ(c.pointer.x, huge.x());
    r.expectValidPosesAnsweredCorrectly(kRadius, kStiffness, "a huge pose");
  }
  // A huge orientation does not matter to a point pointer: the position is answered as usual.
  const Vec3 p = r.probes().front();
  Pose pose;
  pose.position = p;
  pose.orientation = {{1e300, -1e300, 1e300, 1e300}};
  Contact c;
  geometry_msgs::WrenchStamped f;
  ASSERT_TRUE(r.waitAnswer(r.publish(pose), c, f));
  EXPECT_EQ(c.in_contact, bruteForceQuery(r.mesh(), p, kRadius).contact);
  Rig::expectNodesUp("huge poses");
}

TEST(BadInputs, UnknownFrameIsDroppedAndCounted) {
  Rig& r = rig();
  ASSERT_TRUE(r.waitReady());
  for (const char* frame : {"no_such_frame", "/", "a frame with spaces"}) {
    const DetectorStatus before = r.status();
    Pose pose;
    pose.position = r.probes().front();
    pose.frame = frame;
    const ros::Time bad = r.publish(pose);
    r.expectValidPosesAnsweredCorrectly(kRadius, kStiffness, std::string("frame '") + frame + "'");
    EXPECT_FALSE(r.answered(bad)) << frame;
    EXPECT_TRUE(Rig::waitFor([&] { return r.status().dropped_unknown_frame == before.dropped_unknown_frame + 1; }, 5.0))
        << frame << ": not counted";
  }
  Rig::expectNodesUp("unknown frames");
}

TEST(BadInputs, ReconfigureOutOfRangeIsClampedOrRefusedAndPosesStayCorrect) {
  Rig& r = rig();
  ASSERT_TRUE(r.waitReady());
  dynamic_reconfigure::Config applied;

  // NaN passes dynamic_reconfigure's clamp: the detector keeps the current value and says which.
  for (const char* name : {"pointer_radius", "clustering_distance", "stiffness", "max_force"}) {
    const DetectorStatus before = r.status();
    ASSERT_TRUE(r.reconfigure({{name, kNaN}}, {}, applied)) << name;
    EXPECT_TRUE(std::isfinite(Rig::value(applied, name))) << name << " = NaN was applied";
    EXPECT_EQ(Rig::value(applied, "pointer_radius"), kRadius) << name;
    EXPECT_EQ(Rig::value(applied, "clustering_distance"), before.requested_distance) << name;
    EXPECT_EQ(Rig::value(applied, "stiffness"), kStiffness) << name;
    EXPECT_EQ(r.status().requested_distance, before.requested_distance);
    EXPECT_GT(r.expectValidPosesAnsweredCorrectly(kRadius, kStiffness, std::string(name) + " = NaN"), 0u);
  }
  ros::WallDuration(clod_haptics_test::scaled(0.5)).sleep();  // no level change follows a refused distance
  EXPECT_TRUE(std::isfinite(r.status().clustering_distance));

  // Out of range: clamped to cfg/Detector.cfg's bounds, and the answers follow the clamped value.
  ASSERT_TRUE(r.reconfigure({{"pointer_radius", -0.01}}, {}, applied));
  EXPECT_EQ(Rig::value(applied, "pointer_radius"), 0.0);
  r.expectValidPosesAnsweredCorrectly(0.0, kStiffness, "pointer_radius = -0.01 (clamped to 0)");

  // A radius larger than the tube of the torus and than the grid's radius (the hierarchy answers).
  for (double huge : {1e300, kInf}) {
    ASSERT_TRUE(r.reconfigure({{"pointer_radius", huge}}, {}, applied));
    EXPECT_EQ(Rig::value(applied, "pointer_radius"), 0.1);
    EXPECT_GT(r.expectValidPosesAnsweredCorrectly(0.1, kStiffness, "pointer_radius = 1e300/Inf (clamped to 0.1)"),
              r.probes().size() / 2);
  }
  ASSERT_TRUE(r.reconfigure({{"pointer_radius", kRadius}}, {}, applied));

  ASSERT_TRUE(r.reconfigure({{"stiffness", -5.0}}, {}, applied));
  EXPECT_EQ(Rig::value(applied, "stiffness"), 0.0);
  r.expectValidPosesAnsweredCorrectly(kRadius, 0.0, "stiffness = -5 (clamped to 0: no force)");
  ASSERT_TRUE(r.reconfigure({{"stiffness", kStiffness}}, {}, applied));

  ASSERT_TRUE(r.reconfigure({}, {{"detection_mode", "bogus"}}, applied));
  EXPECT_EQ(Rig::text(applied, "detection_mode"), "exact");
  r.expectValidPosesAnsweredCorrectly(kRadius, kStiffness, "detection_mode = bogus");

  // Distances out of range are clamped to [0, 1]; the level of the clamped distance arrives.
  for (const auto& kv : std::vector<std::pair<double, double>>{{-1.0, 0.0}, {1e300, 1.0}, {-kInf, 0.0}}) {
    const DetectorStatus before = r.status();
    ASSERT_TRUE(r.reconfigure({{"clustering_distance", kv.first}}, {}, applied));
    EXPECT_EQ(Rig::value(applied, "clustering_distance"), kv.second);
    if (before.clustering_distance != kv.second) {
      EXPECT_TRUE(Rig::waitFor([&] { return r.status().clustering_distance == kv.second; }, 60.0))
          << "the level for the clamped d = " << kv.second << " never arrived";
    }
    EXPECT_EQ(r.status().level_spheres, r.expectedSpheres(kv.second));
    r.expectValidPosesAnsweredCorrectly(kRadius, kStiffness, "clustering_distance = " + std::to_string(kv.first));
  }
  ASSERT_TRUE(r.reconfigure({{"clustering_distance", kDistance}}, {}, applied));
  EXPECT_TRUE(Rig::waitFor([&] { return r.status().clustering_distance == kDistance; }, 60.0));
  Rig::expectNodesUp("reconfigure");
}

TEST(BadInputs, ServiceRefusesBadDistancesAndKeepsServing) {
  Rig& r = rig();
  ASSERT_TRUE(ros::service::waitForService(kService, ros::Duration(clod_haptics_test::scaled(60.0))));
  for (double d : {-1.0, -1e-12, kNaN, kInf, -kInf, 1e300}) {
    GetSphereSet srv;
    srv.request.distance = d;
    ASSERT_TRUE(ros::service::call(kService, srv)) << "d = " << d << ": the call itself failed";
    bool coreAccepts = true;
    std::size_t expected = 0;
    try {
      expected = r.expectedSpheres(d);
    } catch (const InvalidParameter&) {
      coreAccepts = false;
    }
    if (coreAccepts) {
      EXPECT_TRUE(srv.response.success) << "d = " << d << ": " << srv.response.message;
      EXPECT_EQ(srv.response.sphere_set.spheres.size(), expected) << "d = " << d;
    } else {
      EXPECT_FALSE(srv.response.success) << "d = " << d;
      EXPECT_NE(srv.response.message.find("finite and >= 0"), std::string::npos)
          << "d = " << d << ": unclear message '" << srv.response.message << "'";
      EXPECT_TRUE(srv.response.sphere_set.spheres.empty());
    }
    // The next valid request is served, and matches the core.
    GetSphereSet good;
    good.request.distance = 0.02;
    ASSERT_TRUE(ros::service::call(kService, good)) << "after d = " << d;
    EXPECT_TRUE(good.response.success) << good.response.message;
    EXPECT_EQ(good.response.sphere_set.spheres.size(), r.expectedSpheres(0.02)) << "after d = " << d;
    Rig::expectNodesUp("a request for d = " + std::to_string(d));
  }
}

// ------------------------------------------------------------------------------------------------
// Broken mesh files: the node (or nodelet) exits non-zero with an ERROR naming the file, never hangs.

using clod_haptics_test::Outcome;
Outcome run(const std::string& command, double limit = 60.0) { return clod_haptics_test::run(command, limit); }

void expectCleanFailure(const Outcome& o, const std::string& file) {
  EXPECT_NE(o.exitCode, 0) << o.output;
  EXPECT_NE(o.exitCode, 124) << "timed out (hung) instead of exiting: " << o.output;
  EXPECT_NE(o.exitCode, 137) << "killed (hung) instead of exiting: " << o.output;
  EXPECT_NE(o.exitCode, -1) << "crashed: " << o.output;
  EXPECT_NE(o.output.find(file), std::string::npos) << "the error should name " << file << ": " << o.output;
  EXPECT_TRUE(o.output.find("ERROR") != std::string::npos || o.output.find("FATAL") != std::string::npos) << o.output;
}

const char* kBrokenFiles[] = {"truncated_faces.off", "truncated_vertices.off", "truncated_binary.ply"};

TEST(BadInputs, TruncatedMeshFilesMakeSphereBuilderExitWithAClearError) {
  for (const char* file : kBrokenFiles) {
    expectCleanFailure(
        run(std::string(CLOD_SPHERE_BUILDER_PATH) + " __name:=sb_broken _mesh:=" + CLOD_TEST_DATA_DIR + "/" + file),
        file);
  }
}

TEST(BadInputs, TruncatedMeshFilesMakeTheDetectorNodeExitWithAClearError) {
  for (const char* file : kBrokenFiles) {
    expectCleanFailure(
        run(std::string(CLOD_DETECTOR_PATH) + " __name:=det_broken _mesh:=" + CLOD_TEST_DATA_DIR + "/" + file), file);
  }
}

TEST(BadInputs, TruncatedMeshFileMakesTheStandaloneNodeletExitWithAClearError) {
  const std::string file = kBrokenFiles[0];
  expectCleanFailure(run("rosrun " + clod_haptics_test::nodeletRosrunPrefix() +
                         "nodelet nodelet standalone clod_haptics/Detector __name:=nodelet_broken _mesh:=" +
                         std::string(CLOD_TEST_DATA_DIR) + "/" + file),
                     file);
  // The running nodes did not notice.
  Rig::expectNodesUp("the broken mesh files");
}

}  // namespace
}  // namespace clod_haptics

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_bad_inputs");
  ros::AsyncSpinner spinner(2);
  spinner.start();
  const int result = RUN_ALL_TESTS();
  spinner.stop();
  ros::shutdown();
  return result;
}
