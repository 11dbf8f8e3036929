// rostest: two phantom_bridge nodes on the fake libHD in the namespaces left and right (device_phantom.test):
// each publishes its own device's pose on <ns>/phantom/pose, converted as the drivers do (device (x, y, z)
// millimetres -> ROS (x, -z, y) metres), and each was given its own device_name.
#include <geometry_msgs/PoseStamped.h>
#include <gtest/gtest.h>
#include <ros/ros.h>

#include <atomic>
#include <string>

#include "test_timing.h"

namespace {

struct PoseListener {
  explicit PoseListener(const std::string& topic) { sub = nh.subscribe(topic, 10, &PoseListener::onPose, this); }
  void onPose(const geometry_msgs::PoseStamped::ConstPtr& msg) {
    x = msg->pose.position.x;
    y = msg->pose.position.y;
    z = msg->pose.position.z;
    count.fetch_add(1);
  }
  ros::NodeHandle nh;
  ros::Subscriber sub;
  std::atomic<int> count{0};
  double x = 0, y = 0, z = 0;
};

}  // namespace

TEST(PhantomTwoDevices, EachNamespaceCarriesItsOwnDevice) {
  PoseListener left("/left/phantom/pose"), right("/right/phantom/pose");
  ros::AsyncSpinner spinner(1);
  spinner.start();
  ASSERT_TRUE(clod_haptics_test::waitUntil([&] { return left.count > 20 && right.count > 20; }, 30.0));
  spinner.stop();
  EXPECT_NEAR(left.x, 0.010, 1e-9);
  EXPECT_NEAR(left.y, -0.030, 1e-9);
  EXPECT_NEAR(left.z, 0.020, 1e-9);
  EXPECT_NEAR(right.x, -0.040, 1e-9);
  EXPECT_NEAR(right.y, -0.005, 1e-9);
  EXPECT_NEAR(right.z, 0.000, 1e-9);
  std::string leftName, rightName;
  ros::NodeHandle nh;
  EXPECT_TRUE(nh.getParam("/left/phantom_bridge/device_name", leftName));
  EXPECT_TRUE(nh.getParam("/right/phantom_bridge/device_name", rightName));
  EXPECT_EQ(leftName, "Left Touch");
  EXPECT_EQ(rightName, "Right Touch");
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_device_phantom_two");
  return RUN_ALL_TESTS();
}
