// rostest of marker_stylus (device:=marker): dragging the interactive marker (its feedback topic, as RViz
// publishes it) moves the published pose along the straight line to the marker at the bounded speed, one pose per
// millisecond of header.stamp with consecutive header.seq, and the detector answers those poses as the brute-force
// reference over the mesh says.
#include <geometry_msgs/PoseStamped.h>
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <visualization_msgs/InteractiveMarkerFeedback.h>

#include <algorithm>
#include <mutex>
#include <vector>

#include "clod_haptics/Contact.h"
#include "clod_haptics/core/brute_force.h"
#include "clod_haptics/core/mesh_loader.h"
#include "test_timing.h"

namespace clod_haptics {
namespace {

using clod_haptics_test::waitUntil;

struct Sample {
  std::uint32_t seq;
  double stamp;
  Vec3 p;
};

class MarkerStylusTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ros::NodeHandle nh, pnh("~");
    std::string path;
    pnh.getParam("mesh", path);
    mesh_ = loadMesh(path);
    pnh.param("max_speed", maxSpeed_, 0.2);
    poseSub_ = nh.subscribe("/phantom/pose", 20000, &MarkerStylusTest::onPose, this);
    contactSub_ = nh.subscribe("/detector/contact", 20000, &MarkerStylusTest::onContact, this);
    feedbackPub_ = nh.advertise<visualization_msgs::InteractiveMarkerFeedback>("/stylus_marker/feedback", 10);
    spinner_.start();
  }
  void TearDown() override {  // no callback may run once the members it writes are gone
    spinner_.stop();
    poseSub_.shutdown();
    contactSub_.shutdown();
  }

  void onPose(const geometry_msgs::PoseStampedConstPtr& m) {
    std::lock_guard<std::mutex> lock(mutex_);
    poses_.push_back({m->header.seq, m->header.stamp.toSec(), Vec3(m->pose.position.x, m->pose.position.y,
                                                                     m->pose.position.z)});
  }
  void onContact(const ContactConstPtr& c) {
    std::lock_guard<std::mutex> lock(mutex_);
    contacts_.push_back(*c);
  }
  std::vector<Sample> poses() {
    std::lock_guard<std::mutex> lock(mutex_);
    return poses_;
  }
  void drag(const Vec3& to) {
    visualization_msgs::InteractiveMarkerFeedback f;
    f.header.frame_id = "world";
    f.client_id = "/test";
    f.marker_name = "stylus";
    f.control_name = "move_3d";
    f.event_type = visualization_msgs::InteractiveMarkerFeedback::POSE_UPDATE;
    f.pose.position.x = to.x();
    f.pose.position.y = to.y();
    f.pose.position.z = to.z();
    f.pose.orientation.w = 1.0;
    feedbackPub_.publish(f);
  }

  TriangleMesh mesh_;
  double maxSpeed_ = 0.2;
  ros::Subscriber poseSub_, contactSub_;
  ros::Publisher feedbackPub_;
  ros::AsyncSpinner spinner_{2};
  std::mutex mutex_;
  std::vector<Sample> poses_;
  std::vector<Contact> contacts_;
};

TEST_F(MarkerStylusTest, DraggedMarkerIsFollowedAtOneKilohertzAndAnswered) {
  ASSERT_TRUE(waitUntil([&] { return poses().size() > 200; }, 30.0)) << "no poses on /phantom/pose";
  const Vec3 start = poses().back().p;
  // Starts outside the mesh, above it: the brute-force reference finds no contact there.
  EXPECT_GT(start.z(), mesh_.modelBounds().max().z());
  EXPECT_FALSE(bruteForceSignedQuery(mesh_, start, 0.002).contact);

  // 2 mm inside the torus's outer equator (its outer radius is 0.082 m there).
  const Vec3 target(0.080, 0.0, 0.0);
  ASSERT_TRUE(feedbackPub_.getNumSubscribers() > 0 ||
              waitUntil([&] { return feedbackPub_.getNumSubscribers() > 0; }, 10.0));
  drag(target);
  const double travel = (target - start).norm() / maxSpeed_;  // s
  ASSERT_TRUE(waitUntil([&] { return (poses().back().p - target).norm() < 1e-12; }, 10.0 + 3.0 * travel))
      << "the stylus never reached the marker; last " << poses().back().p.transpose();
  ros::WallDuration(0.3).sleep();  // a few hundred poses at the target, answered

  const std::vector<Sample> all = poses();
  std::vector<double> gaps;
  std::size_t moving = 0;
  const Vec3 axis = (target - start).normalized();
  for (std::size_t k = 1; k < all.size(); ++k) {
    ASSERT_EQ(all[k].seq, all[k - 1].seq + 1) << "a pose was lost or reordered at " << k;
    gaps.push_back(all[k].stamp - all[k - 1].stamp);
    const double step = (all[k].p - all[k - 1].p).norm();
    if (step == 0.0) continue;
    ++moving;
    // Interpolated: on the segment from start to the marker, toward it, at most max_speed per millisecond.
    EXPECT_LE(step, maxSpeed_ * 1e-3 * (1.0 + 1e-9)) << "at " << k;
    const Vec3 off = all[k].p - start;
    EXPECT_LT((off - off.dot(axis) * axis).norm(), 1e-9) << "off the straight line at " << k;
    EXPECT_LT((target - all[k].p).norm(), (target - all[k - 1].p).norm()) << "at " << k;
  }
  // Every step but the last is a full one: the motion takes travel * 1 kHz poses.
  EXPECT_NEAR(static_cast<double>(moving), travel * 1000.0, 2.0);
  std::nth_element(gaps.begin(), gaps.begin() + gaps.size() / 2, gaps.end());
  const double median = gaps[gaps.size() / 2];
  EXPECT_GT(median, 0.8e-3) << "poses stamped " << median * 1e3 << " ms apart, expected 1 ms";
  EXPECT_LT(median, 1.25e-3) << "poses stamped " << median * 1e3 << " ms apart, expected 1 ms";

  // The detector answers the poses at the marker as the brute-force reference does.
  const ContactResult expected = bruteForceSignedQuery(mesh_, target, 0.002);
  ASSERT_TRUE(expected.contact);
  std::lock_guard<std::mutex> lock(mutex_);
  std::size_t atTarget = 0;
  for (const Contact& c : contacts_) {
    if ((Vec3(c.pointer.x, c.pointer.y, c.pointer.z) - target).norm() > 1e-12) continue;
    ++atTarget;
    EXPECT_TRUE(c.in_contact);
    EXPECT_NEAR(c.depth, expected.depth, 1e-9);
  }
  EXPECT_GT(atTarget, 100u) << "the detector answered " << contacts_.size() << " poses, few at the marker";
}

}  // namespace
}  // namespace clod_haptics

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_marker_stylus");
  return RUN_ALL_TESTS();
}
