#pragma once

#include <std_msgs/ColorRGBA.h>
#include <std_msgs/Header.h>
#include <visualization_msgs/Marker.h>
#include <visualization_msgs/MarkerArray.h>

#include <cstdint>
#include <string>
#include <vector>

#include "clod_haptics/core/contact.h"
#include "clod_haptics/core/mesh.h"
#include "clod_haptics/core/sphere_set.h"

namespace clod_haptics {

/** \brief Marker namespaces, so RViz can toggle each part. */
namespace marker_ns {
constexpr const char* kMesh = "mesh";
constexpr const char* kSpheres = "spheres";
constexpr const char* kHitSpheres = "hit_spheres";
constexpr const char* kContact = "contact_point";
constexpr const char* kNormal = "contact_normal";
constexpr const char* kPointer = "pointer";
constexpr const char* kProxy = "proxy";
constexpr const char* kForce = "force";
}  // namespace marker_ns

/** \brief An RGBA colour message. */
std_msgs::ColorRGBA makeColor(float r, float g, float b, float a);

/** \brief The mesh as one TRIANGLE_LIST marker (three points per triangle). */
visualization_msgs::Marker meshMarker(const TriangleMesh& mesh, const std_msgs::Header& header,
                                      const std_msgs::ColorRGBA& color);

/**
 * \brief The mesh file as one MESH_RESOURCE marker (RViz loads the file: a few bytes whatever its size) at pose
 * in header.frame_id, scaled by scale; resource is a package:// or file:// URI.
 */
visualization_msgs::Marker meshResourceMarker(const std::string& resource, const Eigen::Isometry3d& pose, double scale,
                                              const std_msgs::Header& header, const std_msgs::ColorRGBA& color);

/**
 * \brief Moves the ADD markers out.markers[first..] from mesh coordinates to a frame in which the mesh sits at
 * offset (a rigid pose): a list marker's points stay and its pose takes the offset; any other marker's position
 * is transformed.
 */
void applyOffset(const Eigen::Isometry3d& offset, std::size_t first, visualization_msgs::MarkerArray& out);

/** \brief Radius classes per doubling of the radius in appendSphereMarkers: a sphere is drawn at most 2^(1/8) larger. */
constexpr int kSphereClassesPerOctave = 8;

/**
 * \brief The listed spheres (indices == nullptr: every sphere of the set) as SPHERE_LIST markers in namespace ns,
 * one per radius class, ids 0..k-1; returns k. A class holds the radii in (2^((c-1)/8), 2^(c/8)] metres and is
 * drawn at its upper bound: never smaller than a sphere, at most 9% larger. When previousCount exceeds k,
 * DELETE markers for ids k..previousCount-1 follow, so fewer classes leave nothing stale in RViz; pass the
 * returned k as the next previousCount. One SPHERE marker per sphere made a 50,000-sphere level about 15 MB,
 * which roscpp serialises under its process-wide publish lock while the detector's pose thread waits for it;
 * a list is its centres (24 bytes a sphere), copied at once.
 */
std::size_t appendSphereMarkers(const ClodSphereSet& set, const std::vector<std::uint32_t>* indices, const char* ns,
                                const std_msgs::Header& header, const std_msgs::ColorRGBA& color,
                                std::size_t previousCount, visualization_msgs::MarkerArray& out);

/** \brief The pointer (or, with ns marker_ns::kProxy, the proxy) as a SPHERE marker of diameter 2 * radius at p. */
visualization_msgs::Marker pointerMarker(const Vec3& p, double radius, const std_msgs::Header& header,
                                         const std_msgs::ColorRGBA& color, const char* ns = marker_ns::kPointer);

/**
 * \brief The contact point (a magenta SPHERE of diameter 0.12 * arrowLength, smaller than the pointer it lies in)
 * and the normal (a yellow ARROW from the point, length arrowLength) when result.contact; otherwise two DELETE
 * markers that clear them.
 */
void appendContactMarkers(const ContactResult& result, double arrowLength, const std_msgs::Header& header,
                          visualization_msgs::MarkerArray& out);

/**
 * \brief The force as a green ARROW in namespace marker_ns::kForce from `from` along force, lengthPerNewton metres
 * per newton (at most 3 N drawn); a DELETE marker when the force is zero or not finite.
 */
visualization_msgs::Marker forceMarker(const Vec3& from, const Vec3& force, double lengthPerNewton,
                                       const std_msgs::Header& header);

/** \brief A DELETE marker for (ns, id). */
visualization_msgs::Marker deleteMarker(const char* ns, int id, const std_msgs::Header& header);

}  // namespace clod_haptics
