// rostest (device_servo_render.test): the Phantom bridge renders the god-object proxy in the fake device's servo
// callback against the detector's mesh. Each force it reports (~rendered_force) is checked against the pose of the
// same bridge tick by brute force over every triangle: the proxy it implies rests on the surface, and no force
// comes without contact. A reconfigure of the detector's stiffness reaches the servo loop (the implied proxy is
// computed with the new stiffness).
#include <dynamic_reconfigure/Reconfigure.h>
#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/WrenchStamped.h>
#include <gtest/gtest.h>
#include <ros/ros.h>

#include <deque>
#include <map>
#include <mutex>

#include "clod_haptics/core/brute_force.h"
#include "clod_haptics/core/mesh_loader.h"
#include "test_timing.h"

using namespace clod_haptics;

namespace {

constexpr double kRadius = 0.002;  // the shipped launch file's pointer

// Rendered forces paired with the pose of the same servo frame: with servo rendering the bridge stamps the force
// with its device read's time, the stamp that frame's pose carries (the bridge publishes the newest frame of each of
// its ticks: unpaired ones are skipped).
struct Pairs {
  explicit Pairs(ros::NodeHandle& nh) {
    poseSub = nh.subscribe("/phantom/pose", 10000, &Pairs::onPose, this);
    forceSub = nh.subscribe("/phantom_bridge/rendered_force", 10000, &Pairs::onForce, this);
  }
  void onPose(const geometry_msgs::PoseStamped::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex);
    poses[msg->header.stamp] = Vec3(msg->pose.position.x, msg->pose.position.y, msg->pose.position.z);
    while (poses.size() > 5000) poses.erase(poses.begin());
    tryPair();
  }
  void onForce(const geometry_msgs::WrenchStamped::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex);
    if (!collecting) return;
    forces.emplace_back(msg->header.stamp, Vec3(msg->wrench.force.x, msg->wrench.force.y, msg->wrench.force.z));
    tryPair();
  }
  // A force whose pose came (or comes within 100 forces) is paired; older ones are dropped.
  void tryPair() {
    while (!forces.empty()) {
      const auto it = poses.find(forces.front().first);
      if (it != poses.end()) {
        pairs.emplace_back(it->second, forces.front().second);
      } else if (forces.size() < 100) {
        return;
      }
      forces.pop_front();
    }
  }
  std::vector<std::pair<Vec3, Vec3>> take(std::size_t n, double seconds) {
    {
      std::lock_guard<std::mutex> lock(mutex);
      pairs.clear();
      forces.clear();
      collecting = true;
    }
    clod_haptics_test::waitUntil(
        [&] {
          std::lock_guard<std::mutex> lock(mutex);
          return pairs.size() >= n;
        },
        seconds);
    std::lock_guard<std::mutex> lock(mutex);
    collecting = false;
    return pairs;
  }
  std::mutex mutex;
  std::map<ros::Time, Vec3> poses;
  std::deque<std::pair<ros::Time, Vec3>> forces;
  bool collecting = false;
  std::vector<std::pair<Vec3, Vec3>> pairs;
  ros::Subscriber poseSub, forceSub;
};

// Checks every pair: the proxy the force implies (pose + force / stiffness) rests on the surface, r from the
// nearest triangle (brute force), never inside; no force means the pose touches nothing. Returns the pairs in
// contact.
std::size_t expectProxyOnTheSurface(const TriangleMesh& mesh, const std::vector<std::pair<Vec3, Vec3>>& pairs,
                                    double stiffness) {
  constexpr double kSlack = 1e-9;  // the proxy rests a hair above the surface; the message rounds nothing
  std::size_t touching = 0;
  for (const auto& pair : pairs) {
    const Vec3& p = pair.first;
    if (pair.second.norm() == 0.0) {
      EXPECT_FALSE(bruteForceQuery(mesh, p, kRadius - kSlack).contact) << "no force at " << p.transpose();
      continue;
    }
    ++touching;
    const Vec3 proxy = p + pair.second / stiffness;
    const ContactResult ref = bruteForceQuery(mesh, proxy, 1.0);
    EXPECT_NEAR(ref.distance, kRadius, kSlack) << "pose " << p.transpose() << " force " << pair.second.transpose();
  }
  return touching;
}

bool setStiffness(double k) {
  dynamic_reconfigure::Reconfigure srv;
  dynamic_reconfigure::DoubleParameter d;
  d.name = "stiffness";
  d.value = k;
  srv.request.config.doubles.push_back(d);
  return ros::service::waitForService("/detector/set_parameters", ros::Duration(30.0)) &&
         ros::service::call("/detector/set_parameters", srv);
}

}  // namespace

TEST(ServoRender, TheBridgeRendersTheSettledProxyAndFollowsTheStiffness) {
  ros::NodeHandle nh;
  std::string meshPath;
  ASSERT_TRUE(ros::NodeHandle("~").getParam("mesh", meshPath));
  const TriangleMesh mesh = loadMesh(meshPath);
  Pairs pairs(nh);
  ros::AsyncSpinner spinner(2);
  spinner.start();
  ASSERT_TRUE(clod_haptics_test::waitUntil([&] { return pairs.forceSub.getNumPublishers() > 0; }, 60.0));
  // Two seconds of the path: one dive into the top and back.
  auto seen = pairs.take(1500, 20.0);
  ASSERT_GE(seen.size(), 500u);
  EXPECT_GT(expectProxyOnTheSurface(mesh, seen, 400.0), 100u) << "the path should press into the top";
  ASSERT_TRUE(setStiffness(200.0));
  ros::Duration(0.2).sleep();
  seen = pairs.take(1500, 20.0);
  ASSERT_GE(seen.size(), 500u);
  EXPECT_GT(expectProxyOnTheSurface(mesh, seen, 200.0), 100u);
  spinner.stop();
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_device_servo_render");
  return RUN_ALL_TESTS();
}
