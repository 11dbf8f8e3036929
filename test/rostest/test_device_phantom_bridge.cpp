// rostest: phantom_bridge with the simulated backend (a scripted circle). The poses, joint states
// and button come out on the Phantom drivers' topics; the force the device is given (the bridge's
// ~rendered_force, what the simulated device records) is clamped to max_force, slew-limited,
// zero for a NaN command and zero once commands go stale. Parameters (~): the bridge's
// max_force, max_force_rate, force_timeout and its circle (sim/centre, sim/radius), read from the
// bridge's namespace.
#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/WrenchStamped.h>
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <sensor_msgs/JointState.h>
#include <sensor_msgs/Joy.h>

#include <Eigen/Core>
#include <cmath>
#include <limits>
#include <mutex>
#include <vector>

#include "test_timing.h"

namespace {

using Eigen::Vector3d;

struct Rendered {
  double t;
  Vector3d f;
};

class BridgeClient {
 public:
  BridgeClient() : bnh_("/phantom_bridge") {
    bnh_.param("max_force", maxForce_, 0.8);
    bnh_.param("max_force_rate", maxRate_, 100.0);
    bnh_.param("force_timeout", timeout_, 0.05);
    std::vector<double> c;
    bnh_.getParam("sim/centre", c);
    if (c.size() == 3) centre_ = Vector3d(c[0], c[1], c[2]);
    bnh_.param("sim/radius", radius_, 0.03);
    forcePub_ = nh_.advertise<geometry_msgs::WrenchStamped>("/phantom/force_feedback", 100);
    renderedSub_ = nh_.subscribe("/phantom_bridge/rendered_force", 100000, &BridgeClient::onRendered, this);
    poseSub_ = nh_.subscribe("/phantom/pose", 100000, &BridgeClient::onPose, this);
    jointSub_ = nh_.subscribe("/phantom/joint_states", 100, &BridgeClient::onJoints, this);
    buttonSub_ = nh_.subscribe("/phantom/button", 10, &BridgeClient::onButton, this);
  }

  bool waitConnected(double seconds = 60.0) {
    const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(clod_haptics_test::scaled(seconds));
    while (ros::ok() && ros::WallTime::now() < end) {
      if (forcePub_.getNumSubscribers() > 0 && renderedSub_.getNumPublishers() > 0 && rendered().size() > 10)
        return true;
      ros::WallDuration(0.01).sleep();
    }
    return false;
  }

  void sendForce(const Vector3d& f) {
    geometry_msgs::WrenchStamped w;
    w.header.stamp = ros::Time::now();
    w.header.frame_id = "world";
    w.wrench.force.x = f.x();
    w.wrench.force.y = f.y();
    w.wrench.force.z = f.z();
    forcePub_.publish(w);
  }

  /** Sends f at about 200 Hz until pred(latest rendered force) holds or the deadline passes. */
  template <class Pred>
  bool sendUntil(const Vector3d& f, Pred pred, double seconds = 10.0) {
    const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(clod_haptics_test::scaled(seconds));
    while (ros::ok() && ros::WallTime::now() < end) {
      sendForce(f);
      ros::WallDuration(0.005).sleep();
      if (pred(latest())) return true;
    }
    return false;
  }

  /** Keeps sending f for the given time (so the bridge sees it continuously). */
  void sendFor(const Vector3d& f, double seconds) {
    const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(seconds);
    while (ros::ok() && ros::WallTime::now() < end) {
      sendForce(f);
      ros::WallDuration(0.005).sleep();
    }
  }

  Vector3d latest() {
    std::lock_guard<std::mutex> lock(mutex_);
    return rendered_.empty() ? Vector3d::Zero() : rendered_.back().f;
  }
  std::vector<Rendered> rendered() {
    std::lock_guard<std::mutex> lock(mutex_);
    return rendered_;
  }
  std::size_t mark() {
    std::lock_guard<std::mutex> lock(mutex_);
    return rendered_.size();
  }

  ros::NodeHandle nh_, bnh_;
  double maxForce_, maxRate_, timeout_, radius_;
  Vector3d centre_ = Vector3d(0, 0, 0.05);
  ros::Publisher forcePub_;
  ros::Subscriber renderedSub_, poseSub_, jointSub_, buttonSub_;
  std::mutex mutex_;
  std::vector<Rendered> rendered_;
  std::vector<geometry_msgs::PoseStamped> poses_;
  std::vector<sensor_msgs::JointState> joints_;
  std::vector<sensor_msgs::Joy> buttons_;

 private:
  void onRendered(const geometry_msgs::WrenchStamped::ConstPtr& m) {
    std::lock_guard<std::mutex> lock(mutex_);
    rendered_.push_back({m->header.stamp.toSec(), Vector3d(m->wrench.force.x, m->wrench.force.y, m->wrench.force.z)});
  }
  void onPose(const geometry_msgs::PoseStamped::ConstPtr& m) {
    std::lock_guard<std::mutex> lock(mutex_);
    poses_.push_back(*m);
  }
  void onJoints(const sensor_msgs::JointState::ConstPtr& m) {
    std::lock_guard<std::mutex> lock(mutex_);
    joints_.push_back(*m);
  }
  void onButton(const sensor_msgs::Joy::ConstPtr& m) {
    std::lock_guard<std::mutex> lock(mutex_);
    buttons_.push_back(*m);
  }
};

BridgeClient* client = nullptr;

TEST(PhantomBridge, PublishesTheScriptedMotionOnTheDriverTopics) {
  ASSERT_TRUE(client->waitConnected());
  ros::WallDuration(0.5).sleep();
  std::lock_guard<std::mutex> lock(client->mutex_);
  ASSERT_GT(client->poses_.size(), 100u);
  for (const auto& p : client->poses_) {
    const Vector3d x(p.pose.position.x, p.pose.position.y, p.pose.position.z);
    ASSERT_EQ(p.header.frame_id, "world");
    ASSERT_NEAR(x.z(), client->centre_.z(), 1e-9);
    // On the scripted circle (a 64-gon: within its sagitta).
    ASSERT_NEAR((x - client->centre_).norm(), client->radius_, client->radius_ * (1 - std::cos(M_PI / 64)) + 1e-9);
  }
  ASSERT_FALSE(client->joints_.empty());
  EXPECT_EQ(client->joints_.back().name,
            (std::vector<std::string>{"waist", "shoulder", "elbow", "yaw", "pitch", "roll"}));
  ASSERT_EQ(client->buttons_.size(), 1u) << "buttons never change in the script: published once (on change)";
  EXPECT_EQ(client->buttons_[0].buttons, (std::vector<int>{0, 0}));
}

TEST(PhantomBridge, ClampsLargeForcesAndLimitsTheirRate) {
  ASSERT_TRUE(client->waitConnected());
  const std::size_t from = client->mark();
  const Vector3d huge(0.0, 30.0, 40.0);  // 50 N, far above the Touch's peak
  ASSERT_TRUE(client->sendUntil(huge, [&](const Vector3d& f) { return f.norm() > client->maxForce_ - 1e-9; }))
      << "the rendered force never reached max_force";
  client->sendFor(huge, 0.3);
  const auto rendered = client->rendered();
  for (std::size_t i = from; i < rendered.size(); ++i) {
    ASSERT_TRUE(rendered[i].f.allFinite());
    ASSERT_LE(rendered[i].f.norm(), client->maxForce_ + 1e-9) << "rendered " << rendered[i].f.transpose();
    // Clamped along the command's direction.
    if (rendered[i].f.norm() > 1e-6) {
      ASSERT_NEAR(rendered[i].f.normalized().dot(huge.normalized()), 1.0, 1e-9);
    }
    // Slew limit between consecutive servo ticks (20 ms of slack for the two clocks a tick reads).
    if (i > from) {
      const double dt = rendered[i].t - rendered[i - 1].t;
      ASSERT_LE((rendered[i].f - rendered[i - 1].f).norm(), client->maxRate_ * (std::max(0.0, dt) + 0.02) + 1e-9)
          << "step " << i;
    }
  }
  EXPECT_NEAR(client->latest().norm(), client->maxForce_, 1e-9);
}

TEST(PhantomBridge, NanForceGivesZero) {
  ASSERT_TRUE(client->waitConnected());
  const Vector3d ok(0.2, 0.0, 0.0);
  ASSERT_TRUE(client->sendUntil(ok, [&](const Vector3d& f) { return (f - ok).norm() < 1e-9; }));
  const double nan = std::numeric_limits<double>::quiet_NaN();
  ASSERT_TRUE(client->sendUntil(Vector3d(nan, 0.1, 0.0), [](const Vector3d& f) { return f.norm() == 0.0; }))
      << "a NaN command did not zero the force";
  const std::size_t from = client->mark();
  client->sendFor(Vector3d(nan, nan, nan), 0.3);
  const auto rendered = client->rendered();
  ASSERT_GT(rendered.size(), from + 10);
  for (std::size_t i = from; i < rendered.size(); ++i) ASSERT_EQ(rendered[i].f, Vector3d::Zero()) << i;
}

TEST(PhantomBridge, StaleForceGivesZero) {
  ASSERT_TRUE(client->waitConnected());
  const Vector3d ok(0.0, 0.0, 0.3);
  ASSERT_TRUE(client->sendUntil(ok, [&](const Vector3d& f) { return (f - ok).norm() < 1e-9; }));
  // Stop commanding: after force_timeout the bridge must render zero, and keep rendering zero.
  const ros::WallTime stop = ros::WallTime::now();
  while (ros::ok() && client->latest().norm() > 0.0 &&
         ros::WallTime::now() - stop < ros::WallDuration(clod_haptics_test::scaled(10.0))) {
    ros::WallDuration(0.001).sleep();
  }
  ASSERT_EQ(client->latest(), Vector3d::Zero()) << "the force did not go to zero once commands stopped";
  const std::size_t from = client->mark();
  ros::WallDuration(0.3).sleep();
  const auto rendered = client->rendered();
  ASSERT_GT(rendered.size(), from + 10);
  for (std::size_t i = from; i < rendered.size(); ++i) ASSERT_EQ(rendered[i].f, Vector3d::Zero()) << i;
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_device_phantom_bridge");
  ros::AsyncSpinner spinner(2);
  spinner.start();
  BridgeClient c;
  client = &c;
  const int result = RUN_ALL_TESTS();
  spinner.stop();
  return result;
}
