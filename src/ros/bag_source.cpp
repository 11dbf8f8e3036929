#include "clod_haptics/ros/bag_source.h"

#include <geometry_msgs/PoseStamped.h>
#include <rosbag/bag.h>
#include <rosbag/exceptions.h>
#include <rosbag/view.h>
#include <sensor_msgs/JointState.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <map>

#include "clod_haptics/core/user_path.h"

namespace clod_haptics {
namespace device {

namespace {

const std::string kPoseType = "geometry_msgs/PoseStamped";
const std::string kJointType = "sensor_msgs/JointState";

bool endsWith(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

/** Indices of the names x, y, z in a JointState, or false. */
bool xyzIndices(const sensor_msgs::JointState& msg, std::array<std::size_t, 3>& index) {
  static const char* names[3] = {"x", "y", "z"};
  for (int k = 0; k < 3; ++k) {
    auto it = std::find(msg.name.begin(), msg.name.end(), names[k]);
    if (it == msg.name.end()) return false;
    index[k] = static_cast<std::size_t>(it - msg.name.begin());
    if (index[k] >= msg.position.size()) return false;
  }
  return true;
}

double stampOf(const std_msgs::Header& header, const ros::Time& bagTime) {
  return header.stamp.isZero() ? bagTime.toSec() : header.stamp.toSec();
}

std::string listTopics(const std::map<std::string, std::string>& topics) {
  std::string text;
  for (const auto& [topic, type] : topics) text += (text.empty() ? "" : ", ") + topic + " (" + type + ")";
  return text.empty() ? "none" : text;
}

}  // namespace

std::string resolveBagPath(const std::string& path) {
  if (path.empty() || path.front() == '/') return path;
  const UserPathResolution resolved = resolveUserPath(path);
  if (!resolved.found()) throw BagReadError("bag '" + path + "': not found: tried " + resolved.triedText());
  return resolved.path;
}

BagMotion readStylusBag(const std::string& path, const BagReadOptions& options) {
  const std::string where = "bag '" + path + "': ";
  if (!std::ifstream(path).good()) throw BagReadError(where + "cannot open the file (missing or unreadable)");
  if (!(options.positionScale >= 0.0) || !std::isfinite(options.positionScale)) {
    throw BagReadError(where + "position scale must be finite and >= 0 (0 = automatic)");
  }
  rosbag::Bag bag;
  try {
    bag.open(path, rosbag::bagmode::Read);
  } catch (const rosbag::BagUnindexedException&) {
    throw BagReadError(where + "the bag is unindexed (recording interrupted?); run `rosbag reindex` on a copy");
  } catch (const rosbag::BagException& e) {
    throw BagReadError(where + "not a readable rosbag v2 (truncated or corrupt?): " + e.what());
  } catch (const std::exception& e) {
    throw BagReadError(where + "cannot read: " + e.what());
  }

  BagMotion motion;
  StylusSamples samples;
  try {
    std::map<std::string, std::string> topics;
    {
      rosbag::View all(bag);
      for (const rosbag::ConnectionInfo* c : all.getConnections()) topics.emplace(c->topic, c->datatype);
    }

    // Pick the stylus topic.
    std::string topic = options.topic;
    if (!topic.empty()) {
      auto it = topics.find(topic);
      if (it == topics.end() && topic.front() != '/') it = topics.find("/" + topic);
      if (it == topics.end()) {
        throw BagReadError(where + "no topic '" + topic + "'; topics in the bag: " + listTopics(topics));
      }
      topic = it->first;
      if (it->second != kPoseType && it->second != kJointType) {
        throw BagReadError(where + "topic '" + topic + "' is " + it->second + ", expected " + kPoseType + " or " +
                           kJointType + " (x, y, z)");
      }
    } else {
      for (const auto& [name, type] : topics)
        if (type == kPoseType && (topic.empty() || endsWith(name, "/pose"))) topic = name;
      if (topic.empty()) {
        for (const auto& [name, type] : topics) {
          if (type != kJointType || !topic.empty()) continue;
          rosbag::View view(bag, rosbag::TopicQuery(name));
          for (const rosbag::MessageInstance& m : view) {
            auto msg = m.instantiate<sensor_msgs::JointState>();
            std::array<std::size_t, 3> index;
            if (msg && xyzIndices(*msg, index)) topic = name;
            break;
          }
        }
      }
      if (topic.empty()) {
        throw BagReadError(where + "no stylus topic (" + kPoseType + ", or " + kJointType +
                           " with names x, y, z); topics in the bag: " + listTopics(topics));
      }
    }
    motion.topic = topic;
    motion.type = topics.at(topic);
    const bool isPose = motion.type == kPoseType;
    motion.positionScale = options.positionScale > 0.0 ? options.positionScale : (isPose ? 1.0 : 0.001);

    rosbag::View view(bag, rosbag::TopicQuery(topic));
    for (const rosbag::MessageInstance& m : view) {
      ++motion.messages;
      StylusSample s;
      if (isPose) {
        auto msg = m.instantiate<geometry_msgs::PoseStamped>();
        if (!msg) continue;
        if (motion.frameId.empty()) motion.frameId = msg->header.frame_id;
        s.time = stampOf(msg->header, m.getTime());
        s.position =
            motion.positionScale * Eigen::Vector3d(msg->pose.position.x, msg->pose.position.y, msg->pose.position.z);
        const auto& q = msg->pose.orientation;
        s.orientation = Eigen::Quaterniond(q.w, q.x, q.y, q.z);
        if (s.orientation.norm() < 1e-9) s.orientation = Eigen::Quaterniond::Identity();  // unset orientation
      } else {
        auto msg = m.instantiate<sensor_msgs::JointState>();
        std::array<std::size_t, 3> index;
        if (!msg) continue;
        if (!xyzIndices(*msg, index)) {
          throw BagReadError(where + "topic '" + topic + "' message " + std::to_string(motion.messages) +
                             " has no x, y, z positions (names: " + std::to_string(msg->name.size()) + ")");
        }
        s.time = stampOf(msg->header, m.getTime());
        s.position = motion.positionScale *
                     Eigen::Vector3d(msg->position[index[0]], msg->position[index[1]], msg->position[index[2]]);
      }
      samples.push_back(s);
    }
    if (samples.empty()) throw BagReadError(where + "topic '" + topic + "' has no message");

    // Joint angles, if the bag has them.
    std::string jointTopic = options.jointTopic;
    if (!jointTopic.empty() && topics.count(jointTopic) == 0) {
      throw BagReadError(where + "no joint topic '" + jointTopic + "'; topics in the bag: " + listTopics(topics));
    }
    if (jointTopic.empty()) {
      for (const auto& [name, type] : topics)
        if (type == kJointType && name != topic && jointTopic.empty()) jointTopic = name;
    }
    if (!jointTopic.empty()) {
      rosbag::View joints(bag, rosbag::TopicQuery(jointTopic));
      for (const rosbag::MessageInstance& m : joints) {
        auto msg = m.instantiate<sensor_msgs::JointState>();
        if (!msg || msg->position.size() != msg->name.size() || msg->name.empty()) continue;
        JointSample j;
        j.time = stampOf(msg->header, m.getTime());
        j.names = msg->name;
        j.positions = msg->position;
        motion.joints.push_back(std::move(j));
      }
      if (!motion.joints.empty()) motion.jointTopic = jointTopic;
    }
  } catch (const BagReadError&) {
    throw;
  } catch (const rosbag::BagException& e) {
    throw BagReadError(where + "reading failed (truncated or corrupt?): " + e.what());
  } catch (const std::exception& e) {
    throw BagReadError(where + "reading failed: " + e.what());
  }

  const double t0 = [&] {
    double t = std::numeric_limits<double>::infinity();
    for (const StylusSample& s : samples)
      if (std::isfinite(s.time) && s.position.allFinite()) t = std::min(t, s.time);
    return std::isfinite(t) ? t : 0.0;
  }();
  try {
    motion.trajectory = StylusTrajectory(std::move(samples));
  } catch (const std::invalid_argument&) {
    throw BagReadError(where + "topic '" + motion.topic + "' has no finite sample");
  }
  // Joint times on the trajectory's axis (the trajectory starts at its first valid sample).
  for (JointSample& j : motion.joints) j.time -= t0;
  std::sort(motion.joints.begin(), motion.joints.end(),
            [](const JointSample& a, const JointSample& b) { return a.time < b.time; });
  return motion;
}

}  // namespace device
}  // namespace clod_haptics
