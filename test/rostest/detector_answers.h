#pragma once

// What the rostests of the detector share: its answers (contact and force per pose stamp, the last status)
// and a dynamic_reconfigure request of doubles and strings.

#include <dynamic_reconfigure/Reconfigure.h>
#include <geometry_msgs/WrenchStamped.h>
#include <ros/ros.h>

#include <map>
#include <mutex>
#include <string>

#include "clod_haptics/Contact.h"
#include "clod_haptics/DetectorStatus.h"
#include "clod_haptics/core/brute_force.h"
#include "test_timing.h"

namespace clod_haptics_test {

/** \brief Records a detector's ~contact, ~force (by the pose's stamp) and ~status under namespace ns. */
class DetectorAnswers {
 public:
  explicit DetectorAnswers(const std::string& ns) {
    contactSub_ = nh_.subscribe(ns + "/contact", 10000, &DetectorAnswers::onContact, this);
    forceSub_ = nh_.subscribe(ns + "/force", 10000, &DetectorAnswers::onForce, this);
    statusSub_ = nh_.subscribe(ns + "/status", 10, &DetectorAnswers::onStatus, this);
  }
  DetectorAnswers(const DetectorAnswers&) = delete;
  DetectorAnswers& operator=(const DetectorAnswers&) = delete;

  /** \brief The detector publishes contacts and forces to us. */
  bool connected() const { return contactSub_.getNumPublishers() > 0 && forceSub_.getNumPublishers() > 0; }

  /** \brief Waits (scaled seconds) for the contact and the force of a stamp. */
  bool waitAnswer(const ros::Time& stamp, clod_haptics::Contact& contact, geometry_msgs::WrenchStamped& force,
                  double seconds = 5.0) {
    return waitUntil(
        [&] {
          std::lock_guard<std::mutex> lock(mutex_);
          auto c = contacts_.find(stamp);
          auto f = forces_.find(stamp);
          if (c == contacts_.end() || f == forces_.end()) return false;
          contact = c->second;
          force = f->second;
          return true;
        },
        seconds, 0.0005);
  }

  bool hasContact(const ros::Time& stamp) {
    std::lock_guard<std::mutex> lock(mutex_);
    return contacts_.count(stamp) > 0;
  }
  bool hasForce(const ros::Time& stamp) {
    std::lock_guard<std::mutex> lock(mutex_);
    return forces_.count(stamp) > 0;
  }
  std::map<ros::Time, clod_haptics::Contact> contacts() {
    std::lock_guard<std::mutex> lock(mutex_);
    return contacts_;
  }
  clod_haptics::DetectorStatus status() {
    std::lock_guard<std::mutex> lock(mutex_);
    return status_;
  }

 private:
  void onContact(const clod_haptics::ContactConstPtr& c) {
    std::lock_guard<std::mutex> lock(mutex_);
    contacts_[c->header.stamp] = *c;
  }
  void onForce(const geometry_msgs::WrenchStampedConstPtr& f) {
    std::lock_guard<std::mutex> lock(mutex_);
    forces_[f->header.stamp] = *f;
  }
  void onStatus(const clod_haptics::DetectorStatusConstPtr& s) {
    std::lock_guard<std::mutex> lock(mutex_);
    status_ = *s;
  }

  ros::NodeHandle nh_;
  ros::Subscriber contactSub_, forceSub_, statusSub_;
  std::mutex mutex_;
  std::map<ros::Time, clod_haptics::Contact> contacts_;
  std::map<ros::Time, geometry_msgs::WrenchStamped> forces_;
  clod_haptics::DetectorStatus status_;
};

/**
 * \brief The reference for one answer of a detector's pose stream at p. bruteForceQuery, except where the
 * detector answered a contact with the centre inside although no triangle is within r: a stream that was
 * pushed into a part follows it deeper than r (QueryCache), and then the signed reference must agree that
 * the centre is inside, at the same distance.
 */
inline clod_haptics::ContactResult streamReference(const clod_haptics::TriangleMesh& mesh, const clod_haptics::Vec3& p,
                                                   double r, bool answeredInside) {
  clod_haptics::ContactResult ref = clod_haptics::bruteForceQuery(mesh, p, r);
  if (!ref.contact && answeredInside) {
    const clod_haptics::ContactResult deep = clod_haptics::bruteForceSignedQuery(mesh, p, r);
    if (deep.contact && deep.inside) return deep;
  }
  return ref;
}

/** \brief A dynamic_reconfigure request setting the given doubles and strings in one call. */
inline dynamic_reconfigure::Reconfigure reconfigureRequest(const std::map<std::string, double>& doubles,
                                                           const std::map<std::string, std::string>& strings) {
  dynamic_reconfigure::Reconfigure srv;
  for (const auto& kv : doubles) {
    dynamic_reconfigure::DoubleParameter p;
    p.name = kv.first;
    p.value = kv.second;
    srv.request.config.doubles.push_back(p);
  }
  for (const auto& kv : strings) {
    dynamic_reconfigure::StrParameter p;
    p.name = kv.first;
    p.value = kv.second;
    srv.request.config.strs.push_back(p);
  }
  return srv;
}

}  // namespace clod_haptics_test
