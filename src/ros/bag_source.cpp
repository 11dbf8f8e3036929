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

/** Topic name to message type, for every connection in the bag. */
using TopicTypes = std::map<std::string, std::string>;

/** Opens path as a rosbag after checking the options; where starts every message. */
void openBag(rosbag::Bag& bag, const std::string& path, const BagReadOptions& options, const std::string& where) {
  if (!std::ifstream(path).good()) throw BagReadError(where + "cannot open the file (missing or unreadable)");
  if (!(options.positionScale >= 0.0) || !std::isfinite(options.positionScale)) {
    throw BagReadError(where + "position scale must be finite and >= 0 (0 = automatic)");
  }
  try {
    bag.open(path, rosbag::bagmode::Read);
  } catch (const rosbag::BagUnindexedException&) {
    throw BagReadError(where + "the bag is unindexed (recording interrupted?); run `rosbag reindex` on a copy");
  } catch (const rosbag::BagException& e) {
    throw BagReadError(where + "not a readable rosbag v2 (truncated or corrupt?): " + e.what());
  } catch (const std::exception& e) {
    throw BagReadError(where + "cannot read: " + e.what());
  }
}

TopicTypes topicTypes(const rosbag::Bag& bag) {
  TopicTypes topics;
  rosbag::View all(bag);
  for (const rosbag::ConnectionInfo* c : all.getConnections()) topics.emplace(c->topic, c->datatype);
  return topics;
}

/** The topic the user asked for (with or without its leading '/'), checked to be a stylus type. */
std::string requestedStylusTopic(const TopicTypes& topics, const std::string& requested, const std::string& where) {
  auto it = topics.find(requested);
  if (it == topics.end() && requested.front() != '/') it = topics.find("/" + requested);
  if (it == topics.end()) {
    throw BagReadError(where + "no topic '" + requested + "'; topics in the bag: " + listTopics(topics));
  }
  if (it->second != kPoseType && it->second != kJointType) {
    throw BagReadError(where + "topic '" + it->first + "' is " + it->second + ", expected " + kPoseType + " or " +
                       kJointType + " (x, y, z)");
  }
  return it->first;
}

/** The first JointState topic whose first message names x, y, z; empty if none. */
std::string firstXyzJointTopic(const rosbag::Bag& bag, const TopicTypes& topics) {
  for (const auto& [name, type] : topics) {
    if (type != kJointType) continue;
    rosbag::View view(bag, rosbag::TopicQuery(name));
    for (const rosbag::MessageInstance& m : view) {
      auto msg = m.instantiate<sensor_msgs::JointState>();
      std::array<std::size_t, 3> index;
      if (msg && xyzIndices(*msg, index)) return name;
      break;
    }
  }
  return {};
}

/** The stylus topic when the user named none (see BagReadOptions::topic). */
std::string guessStylusTopic(const rosbag::Bag& bag, const TopicTypes& topics, const std::string& where) {
  std::string topic;
  for (const auto& [name, type] : topics)
    if (type == kPoseType && (topic.empty() || endsWith(name, "/pose"))) topic = name;
  if (topic.empty()) topic = firstXyzJointTopic(bag, topics);
  if (topic.empty()) {
    throw BagReadError(where + "no stylus topic (" + kPoseType + ", or " + kJointType +
                       " with names x, y, z); topics in the bag: " + listTopics(topics));
  }
  return topic;
}

/** One PoseStamped message as a sample; false if it is not one. */
bool poseSample(const rosbag::MessageInstance& m, BagMotion& motion, StylusSample& s) {
  auto msg = m.instantiate<geometry_msgs::PoseStamped>();
  if (!msg) return false;
  if (motion.frameId.empty()) motion.frameId = msg->header.frame_id;
  s.time = stampOf(msg->header, m.getTime());
  s.position = motion.positionScale * Eigen::Vector3d(msg->pose.position.x, msg->pose.position.y, msg->pose.position.z);
  const auto& q = msg->pose.orientation;
  s.orientation = Eigen::Quaterniond(q.w, q.x, q.y, q.z);
  if (s.orientation.norm() < 1e-9) s.orientation = Eigen::Quaterniond::Identity();  // unset orientation
  return true;
}

/** One x, y, z JointState message as a sample; false if it is not a JointState. */
bool xyzSample(const rosbag::MessageInstance& m, const BagMotion& motion, StylusSample& s, const std::string& where) {
  auto msg = m.instantiate<sensor_msgs::JointState>();
  if (!msg) return false;
  std::array<std::size_t, 3> index;
  if (!xyzIndices(*msg, index)) {
    throw BagReadError(where + "topic '" + motion.topic + "' message " + std::to_string(motion.messages) +
                       " has no x, y, z positions (names: " + std::to_string(msg->name.size()) + ")");
  }
  s.time = stampOf(msg->header, m.getTime());
  s.position =
      motion.positionScale * Eigen::Vector3d(msg->position[index[0]], msg->position[index[1]], msg->position[index[2]]);
  return true;
}

/** Every sample of motion.topic, counting its messages in motion.messages. */
StylusSamples readStylusSamples(const rosbag::Bag& bag, BagMotion& motion, const std::string& where) {
  const bool isPose = motion.type == kPoseType;
  StylusSamples samples;
  rosbag::View view(bag, rosbag::TopicQuery(motion.topic));
  for (const rosbag::MessageInstance& m : view) {
    ++motion.messages;
    StylusSample s;
    if (isPose ? poseSample(m, motion, s) : xyzSample(m, motion, s, where)) samples.push_back(s);
  }
  if (samples.empty()) throw BagReadError(where + "topic '" + motion.topic + "' has no message");
  return samples;
}

/** The joint topic: the requested one (which must exist), else a JointState topic other than the stylus's. */
std::string jointTopicOf(const TopicTypes& topics, const BagReadOptions& options, const std::string& stylusTopic,
                         const std::string& where) {
  if (!options.jointTopic.empty()) {
    if (topics.count(options.jointTopic) == 0) {
      throw BagReadError(where + "no joint topic '" + options.jointTopic +
                         "'; topics in the bag: " + listTopics(topics));
    }
    return options.jointTopic;
  }
  for (const auto& [name, type] : topics)
    if (type == kJointType && name != stylusTopic) return name;
  return {};
}

/** The joint angles of jointTopic into motion (messages whose names and positions do not match are skipped). */
void readJoints(const rosbag::Bag& bag, const std::string& jointTopic, BagMotion& motion) {
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

/** Reads the stylus topic, and the joint topic if any, into motion; returns the stylus samples. */
StylusSamples readMotion(const rosbag::Bag& bag, const BagReadOptions& options, BagMotion& motion,
                         const std::string& where) {
  const TopicTypes topics = topicTypes(bag);
  motion.topic =
      options.topic.empty() ? guessStylusTopic(bag, topics, where) : requestedStylusTopic(topics, options.topic, where);
  motion.type = topics.at(motion.topic);
  motion.positionScale = options.positionScale > 0.0 ? options.positionScale : (motion.type == kPoseType ? 1.0 : 0.001);
  StylusSamples samples = readStylusSamples(bag, motion, where);
  const std::string jointTopic = jointTopicOf(topics, options, motion.topic, where);
  if (!jointTopic.empty()) readJoints(bag, jointTopic, motion);
  return samples;
}

/** The earliest time of a finite sample (where the trajectory starts), or 0 if none. */
double firstValidTime(const StylusSamples& samples) {
  double t = std::numeric_limits<double>::infinity();
  for (const StylusSample& s : samples)
    if (std::isfinite(s.time) && s.position.allFinite()) t = std::min(t, s.time);
  return std::isfinite(t) ? t : 0.0;
}

/** Builds the trajectory from samples and puts the joint times on its time axis, in order. */
void finishMotion(StylusSamples samples, BagMotion& motion, const std::string& where) {
  const double t0 = firstValidTime(samples);
  try {
    motion.trajectory = StylusTrajectory(std::move(samples));
  } catch (const std::invalid_argument&) {
    throw BagReadError(where + "topic '" + motion.topic + "' has no finite sample");
  }
  for (JointSample& j : motion.joints) j.time -= t0;
  std::sort(motion.joints.begin(), motion.joints.end(),
            [](const JointSample& a, const JointSample& b) { return a.time < b.time; });
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
  rosbag::Bag bag;
  openBag(bag, path, options, where);
  BagMotion motion;
  StylusSamples samples;
  try {
    samples = readMotion(bag, options, motion, where);
  } catch (const BagReadError&) {
    throw;
  } catch (const rosbag::BagException& e) {
    throw BagReadError(where + "reading failed (truncated or corrupt?): " + e.what());
  } catch (const std::exception& e) {
    throw BagReadError(where + "reading failed: " + e.what());
  }
  finishMotion(std::move(samples), motion, where);
  return motion;
}

}  // namespace device
}  // namespace clod_haptics
