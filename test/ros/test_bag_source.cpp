// readStylusBag: PoseStamped bags, the Geomagic Touch JointState (x, y, z millimetres) format,
// and every way a bag can be unusable (missing, not a bag, truncated, unindexed, wrong topic).
// Bags are written with the rosbag C++ API; no roscore needed.
#include <geometry_msgs/PoseStamped.h>
#include <gtest/gtest.h>
#include <rosbag/bag.h>
#include <sensor_msgs/JointState.h>
#include <std_msgs/String.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>

#include "clod_haptics/ros/bag_source.h"
#include "clod_haptics/test_config.h"
#include "../scoped_pwd.h"

using namespace clod_haptics::device;
using Eigen::Vector3d;

namespace {

std::string tempPath(const std::string& name) { return ::testing::TempDir() + "clod_device_" + name; }

Vector3d linePoint(double t) { return Vector3d(0.01 + 0.02 * t, -0.03 * t, 0.05); }

/** A PoseStamped bag of p(t) = linePoint(t) at 1 kHz for duration seconds, plus a chatter topic. */
std::string writePoseBag(const std::string& name, double duration, const std::string& topic = "/phantom/pose") {
  const std::string path = tempPath(name);
  rosbag::Bag bag(path, rosbag::bagmode::Write);
  const ros::Time start(1000.0);
  for (int k = 0; k <= static_cast<int>(duration * 1000); ++k) {
    const double t = k / 1000.0;
    geometry_msgs::PoseStamped msg;
    msg.header.stamp = start + ros::Duration(t);
    msg.header.frame_id = "world";
    const Vector3d p = linePoint(t);
    msg.pose.position.x = p.x();
    msg.pose.position.y = p.y();
    msg.pose.position.z = p.z();
    msg.pose.orientation.w = 1.0;
    bag.write(topic, msg.header.stamp, msg);
  }
  std_msgs::String chatter;
  chatter.data = "hello";
  bag.write("/chatter", start, chatter);
  bag.close();
  return path;
}

/** The Geomagic format: JointState x, y, z in millimetres at 100 Hz, and six joint angles. */
std::string writeGeomagicBag(const std::string& name) {
  const std::string path = tempPath(name);
  rosbag::Bag bag(path, rosbag::bagmode::Write);
  const ros::Time start(2000.0);
  for (int k = 0; k <= 100; ++k) {
    const double t = k / 100.0;
    sensor_msgs::JointState ee;
    ee.header.stamp = start + ros::Duration(t);
    ee.name = {"x", "y", "z"};
    ee.position = {1000 * linePoint(t).x(), 1000 * linePoint(t).y(), 1000 * linePoint(t).z()};
    bag.write("/Geomagic/end_effector_pose", ee.header.stamp, ee);
    sensor_msgs::JointState joints;
    joints.header.stamp = ee.header.stamp;
    joints.name = {"waist", "shoulder", "elbow", "yaw", "pitch", "roll"};
    joints.position = {t, 0, 0, 0, 0, 0};
    bag.write("/Geomagic/joint_states", joints.header.stamp, joints);
  }
  bag.close();
  return path;
}

std::string errorOf(const std::string& path, const BagReadOptions& options = {}) {
  try {
    readStylusBag(path, options);
  } catch (const BagReadError& e) {
    return e.what();
  }
  return "";
}

using clod_test::ScopedPwd;

}  // namespace

TEST(BagSource, RelativeBagPathIsResolvedAgainstTheLaunchDirectory) {
  namespace fs = std::filesystem;
  const fs::path root = fs::path(::testing::TempDir()) / "clod_device_relative_bag";
  fs::remove_all(root);
  fs::create_directories(root / "shell" / "here");
  const std::string written = writePoseBag("relative.bag", 0.1);
  fs::copy_file(written, root / "shell" / "stylus.bag", fs::copy_options::overwrite_existing);
  const std::string expected = fs::canonical(root / "shell" / "stylus.bag").string();
  ScopedPwd pwd((root / "shell" / "here").string());  // as if roslaunch ran in shell/here, the node in ROS_HOME
  EXPECT_EQ(resolveBagPath("../stylus.bag"), expected);
  EXPECT_EQ(readStylusBag(resolveBagPath("../stylus.bag")).messages, 101u);
  // Absolute paths are left to readStylusBag, which names them when missing.
  EXPECT_EQ(resolveBagPath("/nonexistent/dir/stylus.bag"), "/nonexistent/dir/stylus.bag");
  fs::remove_all(root);
}

TEST(BagSource, MissingRelativeBagNamesEveryPathTried) {
  namespace fs = std::filesystem;
  const fs::path shell = fs::weakly_canonical(fs::path(::testing::TempDir()) / "clod_device_shell");
  fs::create_directories(shell);
  ScopedPwd pwd(shell.string());
  try {
    resolveBagPath("../no_such_stylus.bag");
    FAIL() << "a missing relative bag must throw";
  } catch (const BagReadError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("bag '../no_such_stylus.bag'"), std::string::npos) << what;
    EXPECT_NE(
        what.find((shell.parent_path() / "no_such_stylus.bag").string() + " (relative to the launch directory $PWD)"),
        std::string::npos)
        << what;
    EXPECT_NE(what.find(fs::weakly_canonical(fs::current_path() / "../no_such_stylus.bag").string() +
                        " (the node's working directory)"),
              std::string::npos)
        << what;
  }
}

TEST(BagSource, ReadsPoseStampedBags) {
  const std::string path = writePoseBag("pose.bag", 0.5);
  const BagMotion motion = readStylusBag(path);
  EXPECT_EQ(motion.topic, "/phantom/pose");
  EXPECT_EQ(motion.type, "geometry_msgs/PoseStamped");
  EXPECT_EQ(motion.frameId, "world");
  EXPECT_EQ(motion.positionScale, 1.0);
  EXPECT_EQ(motion.messages, 501u);
  ASSERT_EQ(motion.trajectory.size(), 501u);
  EXPECT_NEAR(motion.trajectory.duration(), 0.5, 1e-6);
  for (const StylusSample& s : motion.trajectory.samples()) {
    ASSERT_NEAR((s.position - linePoint(s.time)).norm(), 0.0, 1e-6);
  }
  EXPECT_TRUE(motion.joints.empty());
}

TEST(BagSource, ReadsGeomagicMillimetreRecordingsAndUpsamplesThemTo1kHz) {
  const BagMotion motion = readStylusBag(writeGeomagicBag("geomagic.bag"));
  EXPECT_EQ(motion.topic, "/Geomagic/end_effector_pose");
  EXPECT_EQ(motion.positionScale, 0.001);
  EXPECT_EQ(motion.jointTopic, "/Geomagic/joint_states");
  ASSERT_EQ(motion.joints.size(), 101u);
  EXPECT_NEAR(motion.trajectory.meanRate(), 100.0, 0.01);
  const StylusTrajectory up = motion.trajectory.resampled(1000.0);
  ASSERT_EQ(up.size(), 1001u);
  for (const StylusSample& s : up.samples()) ASSERT_NEAR((s.position - linePoint(s.time)).norm(), 0.0, 1e-6);
  EXPECT_NEAR(interpolateJoints(motion.joints, 0.505).positions[0], 0.505, 1e-6);
}

TEST(BagSource, ExplicitTopicAndScale) {
  const std::string path = writePoseBag("named.bag", 0.1, "/omni1/pose");
  BagReadOptions options;
  options.topic = "omni1/pose";  // without the leading slash
  options.positionScale = 2.0;
  const BagMotion motion = readStylusBag(path, options);
  EXPECT_EQ(motion.topic, "/omni1/pose");
  EXPECT_NEAR((motion.trajectory.samples()[0].position - 2.0 * linePoint(0)).norm(), 0.0, 1e-6);
}

TEST(BagSource, MissingTopicListsWhatIsThere) {
  BagReadOptions options;
  options.topic = "/nope";
  const std::string error = errorOf(writePoseBag("missing_topic.bag", 0.1), options);
  EXPECT_NE(error.find("no topic '/nope'"), std::string::npos) << error;
  EXPECT_NE(error.find("/phantom/pose (geometry_msgs/PoseStamped)"), std::string::npos) << error;
  options.topic = "/chatter";
  const std::string wrongType = errorOf(writePoseBag("wrong_type.bag", 0.1), options);
  EXPECT_NE(wrongType.find("std_msgs/String"), std::string::npos) << wrongType;
}

TEST(BagSource, BagWithoutAStylusTopicIsAnError) {
  const std::string path = tempPath("chatter_only.bag");
  {
    rosbag::Bag bag(path, rosbag::bagmode::Write);
    std_msgs::String s;
    s.data = "x";
    bag.write("/chatter", ros::Time(1.0), s);
  }
  const std::string error = errorOf(path);
  EXPECT_NE(error.find("no stylus topic"), std::string::npos) << error;
}

TEST(BagSource, MissingFileNotABagTruncatedAndUnindexedBagsAreErrors) {
  EXPECT_NE(errorOf("/nonexistent/dir/stylus.bag").find("cannot open"), std::string::npos);

  const std::string text = tempPath("not_a_bag.bag");
  std::ofstream(text) << "this is not a rosbag\n";
  EXPECT_NE(errorOf(text).find("bag '" + text + "'"), std::string::npos);

  // Truncated copies of a good bag: cut at several points, every one must fail cleanly.
  const std::string good = writePoseBag("good.bag", 1.0);
  const auto size = std::filesystem::file_size(good);
  std::ifstream in(good, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  for (double fraction : {0.001, 0.1, 0.5, 0.9, 0.99}) {
    const std::string cut = tempPath("truncated.bag");
    std::ofstream(cut, std::ios::binary | std::ios::trunc)
        .write(bytes.data(), static_cast<std::streamsize>(size * fraction));
    const std::string error = errorOf(cut);
    EXPECT_NE(error.find("bag '" + cut + "'"), std::string::npos) << "fraction " << fraction << ": '" << error << "'";
  }
}

TEST(BagSource, RealGeomagicTouchRecording) {
  const std::string path = std::string(CLOD_SHARED_DIR) + "/data/bags/geomagic_touch_2016-11-29.bag";
  ASSERT_TRUE(std::filesystem::exists(path)) << path << " missing (set CLOD_SHARED_DIR when configuring)";
  const BagMotion motion = readStylusBag(path);
  EXPECT_EQ(motion.topic, "/Geomagic/end_effector_pose");
  EXPECT_EQ(motion.messages, 2743u);
  EXPECT_EQ(motion.trajectory.size(), 2743u);
  EXPECT_NEAR(motion.trajectory.meanRate(), 100.0, 1.0);
  EXPECT_EQ(motion.jointTopic, "/Geomagic/joint_states");
  // The stylus tip stays within the Touch's workspace (about 160 x 120 x 70 mm, a little more at the edges).
  const Eigen::AlignedBox3d box = motion.trajectory.bounds();
  EXPECT_LT(box.sizes().maxCoeff(), 0.3);
  EXPECT_GT(box.sizes().maxCoeff(), 0.05);
  const StylusTrajectory up = motion.trajectory.resampled(1000.0);
  EXPECT_EQ(up.size(), static_cast<std::size_t>(std::floor(motion.trajectory.duration() * 1000 + 1e-9)) + 1);
  // Every upsampled point lies on the segment between the recorded samples around it.
  const StylusSamples& rec = motion.trajectory.samples();
  std::size_t i = 0;
  for (const StylusSample& s : up.samples()) {
    while (i + 2 < rec.size() && rec[i + 1].time <= s.time) ++i;
    const Vector3d a = rec[i].position, b = rec[i + 1].position;
    const double u = (s.time - rec[i].time) / (rec[i + 1].time - rec[i].time);
    ASSERT_NEAR((s.position - (a + u * (b - a))).norm(), 0.0, 1e-9);
  }
}
