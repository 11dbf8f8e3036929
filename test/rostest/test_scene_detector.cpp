// Wiring of the scene detector (node and nodelet): poses in, a ContactArray and a combined force out,
// every object's contact checked against bruteForceQuery on that object's mesh placed where the test
// knows it is (static offsets, a static tf2 frame, and a frame the test itself moves between poses).

#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/WrenchStamped.h>
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <sys/wait.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/static_transform_broadcaster.h>
#include <tf2_ros/transform_broadcaster.h>
#include <tf2_ros/transform_listener.h>
#include <visualization_msgs/MarkerArray.h>

#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <map>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

#include "clod_haptics/ContactArray.h"
#include "clod_haptics/core/brute_force.h"
#include "clod_haptics/core/mesh_loader.h"
#include "clod_haptics/core/probes.h"
#include "clod_haptics/ros/mesh_resource.h"
#include "clod_haptics/ros/scene_config.h"
#include "test_timing.h"
#include "detector_answers.h"

namespace {

using namespace clod_haptics;
constexpr double kRadius = 0.002;
constexpr double kStiffness = 400.0;

Eigen::Isometry3d toIsometry(const geometry_msgs::Transform& t) {
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.translate(Vec3(t.translation.x, t.translation.y, t.translation.z));
  out.rotate(Eigen::Quaterniond(t.rotation.w, t.rotation.x, t.rotation.y, t.rotation.z).normalized());
  return out;
}

geometry_msgs::Transform toTransform(const Eigen::Isometry3d& pose) {
  geometry_msgs::Transform t;
  t.translation.x = pose.translation().x();
  t.translation.y = pose.translation().y();
  t.translation.z = pose.translation().z();
  const Eigen::Quaterniond q(pose.linear());
  t.rotation.w = q.w();
  t.rotation.x = q.x();
  t.rotation.y = q.y();
  t.rotation.z = q.z();
  return t;
}

class SceneDetectorTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ros::NodeHandle pnh("~");
    XmlRpc::XmlRpcValue scene;
    ASSERT_TRUE(pnh.getParam("scene", scene));
    config_ = parseSceneConfig(scene);
    for (const auto& o : config_.objects) {
      MeshLoadOptions options;
      options.scale = o.scale;
      meshes_.push_back(std::make_shared<const TriangleMesh>(loadMesh(resolveMeshPath(o.mesh), options)));
    }
    std::string contactsTopic, forceTopic;
    pnh.param<std::string>("contacts_topic", contactsTopic, "/scene_detector/contacts");
    pnh.param<std::string>("force_topic", forceTopic, "/scene_detector/force");
    tfListener_ = std::make_unique<tf2_ros::TransformListener>(tfBuffer_);
    posePub_ = nh_.advertise<geometry_msgs::PoseStamped>("/stylus/pose", 100);
    contactsSub_ = nh_.subscribe(contactsTopic, 100, &SceneDetectorTest::onContacts, this);
    forceSub_ = nh_.subscribe(forceTopic, 100, &SceneDetectorTest::onForce, this);
    spinner_ = std::make_unique<ros::AsyncSpinner>(2);
    spinner_->start();
    // The static table frame (the scene's torus_small sits on it), latched on /tf_static.
    geometry_msgs::TransformStamped table;
    table.header.stamp = ros::Time::now();
    table.header.frame_id = "world";
    table.child_frame_id = "table";
    table.transform = toTransform(makePose(Vec3(0.0, 0.4, 0.0), 0.5));
    staticBroadcaster_.sendTransform(table);
    setToolPose(makePose(Vec3(-0.3, 0.0, 0.1), 0.0));
    broadcaster_ = std::thread([this] { broadcastTool(); });
    const auto deadline =
        std::chrono::steady_clock::now() + std::chrono::duration<double>(clod_haptics_test::scaled(60.0));
    while ((posePub_.getNumSubscribers() == 0 || contactsSub_.getNumPublishers() == 0) &&
           std::chrono::steady_clock::now() < deadline) {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    ASSERT_GT(posePub_.getNumSubscribers(), 0u) << "scene detector did not subscribe to /stylus/pose";
  }

  void TearDown() override {
    stop_ = true;
    if (broadcaster_.joinable()) broadcaster_.join();
    spinner_->stop();
  }

  static Eigen::Isometry3d makePose(const Vec3& t, double yaw) {
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.translate(t);
    pose.rotate(Eigen::AngleAxisd(yaw, Vec3::UnitZ()) * Eigen::AngleAxisd(0.5 * yaw, Vec3::UnitX()));
    return pose;
  }

  /** The tool frame the test moves (broadcast at 100 Hz by a thread). */
  void setToolPose(const Eigen::Isometry3d& pose) {
    std::lock_guard<std::mutex> lock(mutex_);
    tool_ = pose;
  }
  void broadcastTool() {
    tf2_ros::TransformBroadcaster broadcaster;
    while (!stop_ && ros::ok()) {
      geometry_msgs::TransformStamped t;
      {
        std::lock_guard<std::mutex> lock(mutex_);
        t.transform = toTransform(tool_);
      }
      t.header.stamp = ros::Time::now();
      t.header.frame_id = "world";
      t.child_frame_id = "tool";
      broadcaster.sendTransform(t);
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
  }

  /** Where object i is in the world now, as the test knows it. */
  Eigen::Isometry3d worldFromObject(std::size_t i) {
    const auto& o = config_.objects[i];
    if (o.frameId == config_.frameId) return o.offset;
    if (o.moving) {
      std::lock_guard<std::mutex> lock(mutex_);
      return tool_ * o.offset;
    }
    const auto tf = tfBuffer_.lookupTransform(config_.frameId, o.frameId, ros::Time(0),
                                              ros::Duration(clod_haptics_test::scaled(10.0)));
    return toIsometry(tf.transform) * o.offset;
  }

  void onContacts(const ContactArrayConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    replies_[msg->header.stamp.toNSec()] = msg;
    cv_.notify_all();
  }
  void onForce(const geometry_msgs::WrenchStampedConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    forces_[msg->header.stamp.toNSec()] = msg;
    cv_.notify_all();
  }

  /** Sends one pose and waits for its answer (null after the timeout). */
  ContactArrayConstPtr ask(const Vec3& p, const std::string& frame = "world", double timeout = 3.0) {
    geometry_msgs::PoseStamped pose;
    pose.header.stamp = ros::Time::now() + ros::Duration(0, static_cast<std::int32_t>(++counter_));
    pose.header.frame_id = frame;
    pose.pose.position.x = p.x();
    pose.pose.position.y = p.y();
    pose.pose.position.z = p.z();
    pose.pose.orientation.w = 1.0;
    posePub_.publish(pose);
    const std::uint64_t key = pose.header.stamp.toNSec();
    std::unique_lock<std::mutex> lock(mutex_);
    cv_.wait_for(lock, std::chrono::duration<double>(clod_haptics_test::scaled(timeout)),
                 [&] { return replies_.count(key) > 0 && forces_.count(key) > 0; });
    auto it = replies_.find(key);
    if (it == replies_.end()) return nullptr;
    lastForce_ = forces_.count(key) ? forces_[key] : nullptr;
    return it->second;
  }

  /** Checks an answer against brute force on every object at the given world poses. */
  void expectMatches(const ContactArray& answer, const Vec3& p,
                     const std::vector<Eigen::Isometry3d, Eigen::aligned_allocator<Eigen::Isometry3d>>& poses,
                     const Eigen::Matrix3d& sceneFromPoseFrame = Eigen::Matrix3d::Identity()) {
    ASSERT_EQ(answer.header.frame_id, config_.frameId);
    ASSERT_EQ(answer.contacts.size(), answer.objects.size());
    ASSERT_EQ(answer.contacts.size(), answer.object_indices.size());
    std::size_t k = 0;
    Vec3 penetration = Vec3::Zero();
    for (std::size_t i = 0; i < meshes_.size(); ++i) {
      const bool listed = k < answer.contacts.size() && answer.object_indices[k] == i;
      const ContactResult ref = clod_haptics_test::streamReference(*meshes_[i], poses[i].inverse() * p, kRadius,
                                                                   listed && answer.contacts[k].inside);
      if (std::abs(ref.distance - kRadius) <= 1e-9 * kRadius) {  // rounding may decide either way
        if (listed) ++k;
        continue;
      }
      ASSERT_EQ(listed, ref.contact) << config_.objects[i].name << " at " << p.transpose() << ", reference distance "
                                     << ref.distance;
      if (!listed) continue;
      const Contact& c = answer.contacts[k];
      EXPECT_EQ(answer.objects[k], config_.objects[i].name);
      ASSERT_TRUE(c.in_contact);
      ASSERT_NEAR(c.distance, ref.distance, 1e-9);
      const Vec3 point = poses[i] * ref.point;
      ASSERT_NEAR(c.point.x, point.x(), 1e-7);
      ASSERT_NEAR(c.point.y, point.y(), 1e-7);
      ASSERT_NEAR(c.point.z, point.z(), 1e-7);
      penetration += c.depth * Vec3(c.normal.x, c.normal.y, c.normal.z);
      ++k;
    }
    ASSERT_EQ(k, answer.contacts.size());
    EXPECT_EQ(answer.in_contact, !answer.contacts.empty());
    EXPECT_NEAR(answer.penetration.x, penetration.x(), 1e-9);
    EXPECT_NEAR(answer.force.x, kStiffness * penetration.x(), 1e-6);
    EXPECT_NEAR(answer.force.y, kStiffness * penetration.y(), 1e-6);
    EXPECT_NEAR(answer.force.z, kStiffness * penetration.z(), 1e-6);
    // The wrench is the same force expressed in the pose's frame, where the device renders it.
    ASSERT_TRUE(lastForce_);
    const Vec3 inPoseFrame = sceneFromPoseFrame.transpose() * Vec3(answer.force.x, answer.force.y, answer.force.z);
    EXPECT_NEAR(lastForce_->wrench.force.x, inPoseFrame.x(), 1e-9);
    EXPECT_NEAR(lastForce_->wrench.force.y, inPoseFrame.y(), 1e-9);
    EXPECT_NEAR(lastForce_->wrench.force.z, inPoseFrame.z(), 1e-9);
    EXPECT_EQ(answer.objects_queried + answer.objects_rejected + answer.objects_without_pose, meshes_.size());
  }

  /** Probes near object i at its current pose (world), both sides of the surface. */
  std::vector<Vec3> probesNear(std::size_t i, std::size_t count, std::uint64_t seed) {
    std::vector<Vec3> out;
    const Eigen::Isometry3d pose = worldFromObject(i);
    for (const Vec3& p : nearSurfaceProbes(*meshes_[i], count, 2.5 * kRadius, seed)) out.push_back(pose * p);
    return out;
  }

  std::vector<Eigen::Isometry3d, Eigen::aligned_allocator<Eigen::Isometry3d>> currentPoses() {
    std::vector<Eigen::Isometry3d, Eigen::aligned_allocator<Eigen::Isometry3d>> poses;
    for (std::size_t i = 0; i < meshes_.size(); ++i) poses.push_back(worldFromObject(i));
    return poses;
  }

  std::size_t movingIndex() const {
    for (std::size_t i = 0; i < config_.objects.size(); ++i)
      if (config_.objects[i].moving) return i;
    return 0;
  }

  ros::NodeHandle nh_;
  SceneConfig config_;
  std::vector<std::shared_ptr<const TriangleMesh>> meshes_;
  tf2_ros::Buffer tfBuffer_;
  std::unique_ptr<tf2_ros::TransformListener> tfListener_;
  ros::Publisher posePub_;
  ros::Subscriber contactsSub_, forceSub_;
  std::unique_ptr<ros::AsyncSpinner> spinner_;
  std::thread broadcaster_;
  tf2_ros::StaticTransformBroadcaster staticBroadcaster_;
  std::atomic<bool> stop_{false};
  std::mutex mutex_;
  std::condition_variable cv_;
  Eigen::Isometry3d tool_ = Eigen::Isometry3d::Identity();
  std::map<std::uint64_t, ContactArrayConstPtr> replies_;
  std::map<std::uint64_t, geometry_msgs::WrenchStampedConstPtr> forces_;
  geometry_msgs::WrenchStampedConstPtr lastForce_;
  std::uint32_t counter_ = 0;
};

TEST_F(SceneDetectorTest, EveryObjectMatchesBruteForce) {
  std::this_thread::sleep_for(
      std::chrono::duration<double>(clod_haptics_test::scaled(0.5)));  // the tool frame reaches the detector
  const auto poses = currentPoses();
  std::vector<std::size_t> touchedPerObject(meshes_.size(), 0);
  for (std::size_t i = 0; i < meshes_.size(); ++i) {
    for (const Vec3& p : probesNear(i, 40, 10 + i)) {
      const auto answer = ask(p);
      ASSERT_TRUE(answer) << "no answer to a pose near " << config_.objects[i].name;
      expectMatches(*answer, p, poses);
      if (HasFatalFailure()) return;
      for (auto index : answer->object_indices) ++touchedPerObject[index];
    }
  }
  for (std::size_t i = 0; i < meshes_.size(); ++i)
    EXPECT_GT(touchedPerObject[i], 5u) << config_.objects[i].name << " was never touched";
  // Far from everything: every object rejected by its bound, nothing touched.
  const auto far = ask(Vec3(5.0, 5.0, 5.0));
  ASSERT_TRUE(far);
  EXPECT_FALSE(far->in_contact);
  EXPECT_EQ(far->objects_rejected, meshes_.size());
}

TEST_F(SceneDetectorTest, ObjectMovedByTf2BetweenPoses) {
  const std::size_t moving = movingIndex();
  ASSERT_TRUE(config_.objects[moving].moving);
  const Eigen::Isometry3d first = makePose(Vec3(-0.3, 0.0, 0.1), 0.0);
  const Eigen::Isometry3d second = makePose(Vec3(-0.25, -0.35, 0.2), 1.2);
  std::vector<Vec3> nearFirst;
  for (int phase = 0; phase < 3; ++phase) {
    const Eigen::Isometry3d tool = phase == 1 ? second : first;
    setToolPose(tool);
    std::this_thread::sleep_for(std::chrono::milliseconds(600));  // only the new pose is in the tf2 buffer window
    const auto poses = currentPoses();
    std::vector<Vec3> probes = probesNear(moving, 60, 70 + phase);
    if (phase == 0) nearFirst = probes;
    if (phase == 1) probes.insert(probes.end(), nearFirst.begin(), nearFirst.end());  // the old place, now empty
    std::size_t touchedMoving = 0;
    for (const Vec3& p : probes) {
      const auto answer = ask(p);
      ASSERT_TRUE(answer);
      expectMatches(*answer, p, poses);
      if (HasFatalFailure()) return;
      for (auto index : answer->object_indices) touchedMoving += index == moving;
    }
    EXPECT_GT(touchedMoving, 10u) << "phase " << phase;
  }
}

TEST_F(SceneDetectorTest, PoseInAnotherFrameAndBadPoses) {
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  // A pose given in the table frame: the detector transforms it into the scene frame.
  const auto table = toIsometry(
      tfBuffer_.lookupTransform("world", "table", ros::Time(0), ros::Duration(clod_haptics_test::scaled(10.0)))
          .transform);
  const auto poses = currentPoses();
  std::size_t touched = 0;
  for (const Vec3& world : probesNear(2, 30, 5)) {
    const auto answer = ask(table.inverse() * world, "table");
    ASSERT_TRUE(answer);
    expectMatches(*answer, world, poses, table.linear());
    if (HasFatalFailure()) return;
    touched += answer->in_contact;
  }
  EXPECT_GT(touched, 5u);
  // NaN and an unknown frame are dropped (no answer); the detector keeps answering.
  EXPECT_FALSE(ask(Vec3(NAN, 0.0, 0.0), "world", 0.5));
  EXPECT_FALSE(ask(Vec3(0.0, 0.0, 0.0), "no_such_frame", 0.5));
  EXPECT_TRUE(ask(Vec3(0.0, 0.0, 0.0)));
}

TEST_F(SceneDetectorTest, LevelsReplaceBruteForceOnceReady) {
  // Levels arrive from the cache or a build; afterwards no object is answered by brute force.
  const Vec3 p = worldFromObject(0) * meshes_[0]->vertices[0];
  const auto deadline =
      std::chrono::steady_clock::now() + std::chrono::duration<double>(clod_haptics_test::scaled(120.0));
  ContactArrayConstPtr answer;
  do {
    answer = ask(p);
    ASSERT_TRUE(answer);
    if (answer->objects_brute_force == 0 && !answer->contacts.empty() &&
        std::isfinite(answer->contacts[0].clustering_distance))
      break;
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  } while (std::chrono::steady_clock::now() < deadline);
  ASSERT_TRUE(answer->in_contact);
  EXPECT_EQ(answer->objects_brute_force, 0u);
  EXPECT_DOUBLE_EQ(answer->contacts[0].clustering_distance, config_.objects[0].distance);
  EXPECT_GT(answer->contacts[0].level_spheres, 0u);
}

TEST_F(SceneDetectorTest, MarkersOnceForMeshesAndOnlyOnChange) {
  std::mutex m;
  std::vector<visualization_msgs::MarkerArrayConstPtr> arrays;
  ros::Subscriber sub = nh_.subscribe<visualization_msgs::MarkerArray>(
      "/scene_detector/markers", 100, [&](const visualization_msgs::MarkerArrayConstPtr& msg) {
        std::lock_guard<std::mutex> lock(m);
        arrays.push_back(msg);
      });
  auto count = [&](const std::string& ns, int type, std::size_t from = 0) {
    std::lock_guard<std::mutex> lock(m);
    std::size_t n = 0;
    for (std::size_t k = from; k < arrays.size(); ++k)
      for (const auto& marker : arrays[k]->markers) n += marker.ns == ns && (type < 0 || marker.type == type);
    return n;
  };
  const auto deadline =
      std::chrono::steady_clock::now() + std::chrono::duration<double>(clod_haptics_test::scaled(10.0));
  while (count("scene_mesh", -1) < meshes_.size() && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  // Every mesh once, by reference (a few bytes whatever its size), in its own frame.
  ASSERT_EQ(count("scene_mesh", visualization_msgs::Marker::MESH_RESOURCE), meshes_.size());
  {
    std::lock_guard<std::mutex> lock(m);
    for (const auto& marker : arrays.front()->markers)
      if (marker.ns == "scene_mesh") {
        EXPECT_EQ(marker.header.frame_id, config_.objects.at(marker.id).frameId);
      }
  }
  // A contact shows up as a contact marker with the object's index as id.
  const Vec3 p = worldFromObject(0) * meshes_[0]->vertices[0];
  ASSERT_TRUE(ask(p));
  std::this_thread::sleep_for(std::chrono::duration<double>(clod_haptics_test::scaled(0.4)));
  bool contactShown = false;
  {
    std::lock_guard<std::mutex> lock(m);
    for (const auto& a : arrays)
      for (const auto& marker : a->markers)
        contactShown |= marker.ns == "contact_point" && marker.id == 0 && marker.action == visualization_msgs::Marker::ADD;
  }
  EXPECT_TRUE(contactShown);
  // Nothing changes (no pose, same pointer): neither the meshes nor the pointer are published again.
  std::size_t before;
  {
    std::lock_guard<std::mutex> lock(m);
    before = arrays.size();
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(800));
  EXPECT_EQ(count("scene_mesh", -1, before), 0u);
  EXPECT_EQ(count("pointer", -1, before), 0u);
  EXPECT_EQ(count("scene_mesh", -1), meshes_.size()) << "meshes republished without a new subscriber";
}

/** Runs the scene_detector binary with a time limit; returns its exit code and output. */
std::pair<int, std::string> runSceneDetector(const std::string& name) {
  FILE* pipe = popen(("timeout " + std::to_string(clod_haptics_test::scaled(60.0)) + " " +
                      std::string(CLOD_SCENE_DETECTOR_PATH) + " __name:=" + name + " 2>&1")
                         .c_str(),
                     "r");
  if (!pipe) return {-1, ""};
  std::string output;
  std::array<char, 512> buffer;
  while (fgets(buffer.data(), buffer.size(), pipe)) output += buffer.data();
  const int status = pclose(pipe);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, output};
}

/** A bad scene makes the node log a clear ERROR naming the problem and exit non-zero (not hang or crash). */
void expectCleanFailure(const std::string& name, const std::string& mention) {
  const auto [code, output] = runSceneDetector(name);
  EXPECT_NE(code, 0) << output;
  EXPECT_NE(code, 124) << "hung instead of exiting: " << output;
  EXPECT_NE(code, -1) << "crashed: " << output;
  EXPECT_NE(output.find("ERROR"), std::string::npos) << output;
  EXPECT_NE(output.find(mention), std::string::npos) << "the error should mention '" << mention << "': " << output;
}

XmlRpc::XmlRpcValue sceneWith(const XmlRpc::XmlRpcValue& object) {
  XmlRpc::XmlRpcValue scene, objects;
  scene["frame_id"] = std::string("world");
  objects.setSize(1);
  objects[0] = object;
  scene["objects"] = objects;
  return scene;
}

TEST(SceneDetectorBadScenes, ExitWithAClearError) {
  expectCleanFailure("scene_none", "scene_none/scene");  // no ~scene at all
  XmlRpc::XmlRpcValue noMesh;
  noMesh["name"] = std::string("lonely");
  ros::param::set("/scene_no_mesh/scene", sceneWith(noMesh));
  expectCleanFailure("scene_no_mesh", "'lonely') has no 'mesh'");
  XmlRpc::XmlRpcValue missing;
  missing["name"] = std::string("ghost");
  missing["mesh"] = std::string("/nonexistent/ghost.obj");
  ros::param::set("/scene_missing_file/scene", sceneWith(missing));
  expectCleanFailure("scene_missing_file", "/nonexistent/ghost.obj");
  XmlRpc::XmlRpcValue badScale;
  badScale["name"] = std::string("flat");
  badScale["mesh"] = std::string("package://clod_haptics/data/meshes/torus.obj");
  badScale["scale"] = 0.0;
  ros::param::set("/scene_bad_scale/scene", sceneWith(badScale));
  expectCleanFailure("scene_bad_scale", "scale must be positive");
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_scene_detector");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
