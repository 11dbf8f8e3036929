#pragma once

#include <geometry_msgs/Pose.h>
#include <geometry_msgs/Transform.h>
#include <geometry_msgs/WrenchStamped.h>
#include <std_msgs/Header.h>

#include <string>

#include <Eigen/Geometry>

#include "clod_haptics/Contact.h"
#include "clod_haptics/SphereSet.h"
#include "clod_haptics/core/contact.h"
#include "clod_haptics/core/sphere_set.h"

namespace clod_haptics {

/** \brief Converts a core sphere set to its message (the header names the mesh frame). */
void toMsg(const ClodSphereSet& set, const std_msgs::Header& header, SphereSet& msg);

/**
 * \brief Converts a sphere set message back to the core struct.
 * \throws FormatError when a radius or centre is not finite or the offsets cannot be rebuilt.
 */
ClodSphereSet fromMsg(const SphereSet& msg);


/**
 * \brief Fills a contact message from a core result; pointer and radius are the query's, in the
 * mesh frame (the proxy field is set to the pointer). Allocation-free apart from what the message already owns.
 */
void toMsg(const ContactResult& result, const Vec3& pointer, double radius, Contact& msg);

/** \brief A rigid transform as a pose message. */
geometry_msgs::Pose toPose(const Eigen::Isometry3d& pose);

/** \brief A transform message as a rigid transform (the quaternion normalised). */
Eigen::Isometry3d toIsometry(const geometry_msgs::Transform& transform);

/** \brief Writes a force into a wrench message (torque zero). */
void toMsg(const Vec3& force, geometry_msgs::Wrench& msg);

/** \brief True when every position and orientation component of the pose is finite. */
bool isFinite(const geometry_msgs::Pose& pose);

/** \brief Point message from an Eigen vector. */
geometry_msgs::Point toPoint(const Vec3& v);
/** \brief Vector3 message from an Eigen vector. */
geometry_msgs::Vector3 toVector3(const Vec3& v);
/** \brief Eigen vector from a Point message. */
Vec3 fromPoint(const geometry_msgs::Point& p);

}  // namespace clod_haptics
