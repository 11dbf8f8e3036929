// rostest: bag_replay drives the detector end to end. Every pose bag_replay publishes must be
// answered by exactly one contact message, at the same position, and the contact must match the
// core's brute-force reference for that pose. Parameters (~): mesh (path or package://), scale,
// bag (the bag bag_replay plays), rate (its ~rate), detector (namespace, default /detector),
// min_in_contact / min_free (poses of each kind the motion must produce, so the test can fail).
#include <geometry_msgs/PoseStamped.h>
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <std_msgs/UInt64.h>

#include <cmath>
#include <map>
#include <mutex>

#include "clod_haptics/Contact.h"
#include "clod_haptics/core/brute_force.h"
#include "clod_haptics/core/mesh_loader.h"
#include "clod_haptics/ros/bag_source.h"
#include "clod_haptics/ros/mesh_resource.h"
#include "test_timing.h"
#include "detector_answers.h"

namespace clod_haptics {
namespace {

class ReplayObserver {
 public:
  void onPose(const geometry_msgs::PoseStamped::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    poses_[msg->header.stamp] = Vec3(msg->pose.position.x, msg->pose.position.y, msg->pose.position.z);
    poseOrder_.push_back(msg->header.stamp);
  }
  void onContact(const Contact::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    ++contactMessages_;
    contacts_[msg->header.stamp] = *msg;
  }
  void onDone(const std_msgs::UInt64::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    done_ = static_cast<long long>(msg->data);
  }

  std::mutex mutex_;
  std::map<ros::Time, Vec3> poses_;
  std::vector<ros::Time> poseOrder_;
  std::map<ros::Time, Contact> contacts_;
  std::size_t contactMessages_ = 0;
  long long done_ = -1;
};

TEST(DeviceBagReplay, EveryReplayedPoseIsAnsweredAndMatchesBruteForce) {
  ros::NodeHandle nh, pnh("~");
  std::string meshUri, bagPath, detector;
  ASSERT_TRUE(pnh.getParam("mesh", meshUri));
  ASSERT_TRUE(pnh.getParam("bag", bagPath));
  pnh.param<std::string>("detector", detector, "/detector");
  MeshLoadOptions options;
  pnh.param("scale", options.scale, 1.0);
  double rate = 1000.0;
  pnh.param("rate", rate, rate);
  int minInContact = 100, minFree = 100;
  pnh.param("min_in_contact", minInContact, minInContact);
  pnh.param("min_free", minFree, minFree);
  const TriangleMesh mesh = loadMesh(resolveMeshPath(meshUri), options);
  // The count bag_replay must publish: the recording resampled at `rate`, read independently here.
  const device::BagMotion motion = device::readStylusBag(bagPath);
  const std::size_t expectedPoses =
      static_cast<std::size_t>(std::floor(motion.trajectory.duration() * rate + 1e-9)) + 1;

  ReplayObserver observer;
  ros::AsyncSpinner spinner(2);
  spinner.start();
  ros::Subscriber contactSub = nh.subscribe(detector + "/contact", 100000, &ReplayObserver::onContact, &observer);
  ros::Subscriber doneSub = nh.subscribe("/bag_replay/done", 1, &ReplayObserver::onDone, &observer);
  // Subscribe to the poses only once the contact connection stands: bag_replay waits for two
  // pose subscribers (the detector and this test) before it starts, so nothing is missed.
  const ros::WallTime connectDeadline = ros::WallTime::now() + ros::WallDuration(clod_haptics_test::scaled(60.0));
  while (ros::ok() && contactSub.getNumPublishers() == 0 && ros::WallTime::now() < connectDeadline) {
    ros::WallDuration(0.01).sleep();
  }
  ASSERT_GT(contactSub.getNumPublishers(), 0u) << "no detector publishing " << detector << "/contact";
  ros::Subscriber poseSub = nh.subscribe("/phantom/pose", 100000, &ReplayObserver::onPose, &observer);

  // The replay takes the recording's duration divided by its rate scale: wait for its end.
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(clod_haptics_test::scaled(240.0));
  while (ros::ok() && ros::WallTime::now() < deadline) {
    {
      std::lock_guard<std::mutex> lock(observer.mutex_);
      if (observer.done_ >= 0 && observer.contactMessages_ >= static_cast<std::size_t>(observer.done_) &&
          observer.poses_.size() >= static_cast<std::size_t>(observer.done_))
        break;
    }
    ros::WallDuration(0.05).sleep();
  }
  ros::WallDuration(0.5).sleep();  // anything extra (a duplicate answer) would arrive now

  std::lock_guard<std::mutex> lock(observer.mutex_);
  ASSERT_GE(observer.done_, 0) << "bag_replay never reported the end of its pass";
  EXPECT_EQ(static_cast<std::size_t>(observer.done_), expectedPoses);
  EXPECT_EQ(observer.poses_.size(), expectedPoses);
  EXPECT_EQ(observer.poseOrder_.size(), observer.poses_.size()) << "two poses shared a stamp";
  EXPECT_EQ(observer.contactMessages_, observer.poses_.size()) << "poses unanswered or answered twice";

  std::size_t inContact = 0, free = 0, borderline = 0, missing = 0, mismatches = 0;
  for (const auto& [stamp, position] : observer.poses_) {
    auto it = observer.contacts_.find(stamp);
    if (it == observer.contacts_.end()) {
      ++missing;
      continue;
    }
    const Contact& c = it->second;
    const Vec3 pointer(c.pointer.x, c.pointer.y, c.pointer.z);
    ASSERT_NEAR((pointer - position).norm(), 0.0, 1e-12) << "the detector answered another position";
    const double r = c.pointer_radius;
    const ContactResult ref = clod_haptics_test::streamReference(mesh, position, r, c.in_contact && c.inside);
    if (std::abs(ref.distance - r) < 1e-9) {  // on the pointer's surface: either answer is right
      ++borderline;
      continue;
    }
    if (c.in_contact != ref.contact) {
      if (++mismatches <= 5) {
        ADD_FAILURE() << "pose (" << position.transpose() << "): detector in_contact=" << int(c.in_contact)
                      << ", brute force " << ref.contact << " at distance " << ref.distance << " (r " << r << ")";
      }
      continue;
    }
    if (ref.contact) {
      ++inContact;
      EXPECT_NEAR(c.distance, ref.distance, 1e-9);
      EXPECT_NEAR((Vec3(c.point.x, c.point.y, c.point.z) - ref.point).norm(), 0.0, 1e-9);
    } else {
      ++free;
    }
  }
  EXPECT_EQ(missing, 0u);
  EXPECT_EQ(mismatches, 0u);
  EXPECT_GE(inContact, static_cast<std::size_t>(minInContact));
  EXPECT_GE(free, static_cast<std::size_t>(minFree));
  RecordProperty("poses", static_cast<int>(observer.poses_.size()));
  RecordProperty("in_contact", static_cast<int>(inContact));
  std::printf("bag replay: %zu poses, %zu in contact, %zu free, %zu borderline, all matching brute force\n",
              observer.poses_.size(), inContact, free, borderline);
}

}  // namespace
}  // namespace clod_haptics

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_device_bag_replay");
  return RUN_ALL_TESTS();
}
