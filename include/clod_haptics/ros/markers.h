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
}  // namespace marker_ns

/** \brief An RGBA colour message. */
std_msgs::ColorRGBA makeColor(float r, float g, float b, float a);

/** \brief The mesh as one TRIANGLE_LIST marker (three points per triangle). */
visualization_msgs::Marker meshMarker(const TriangleMesh& mesh, const std_msgs::Header& header,
                                      const std_msgs::ColorRGBA& color);

/**
 * \brief One SPHERE marker per listed sphere (ids 0..n-1 in namespace ns), diameter 2 * radius.
 * When previousCount exceeds the list, DELETE markers for ids n..previousCount-1 follow, so a
 * shrinking list leaves nothing stale in RViz. indices == nullptr means every sphere of the set.
 */
void appendSphereMarkers(const ClodSphereSet& set, const std::vector<std::uint32_t>* indices, const char* ns,
                         const std_msgs::Header& header, const std_msgs::ColorRGBA& color, std::size_t previousCount,
                         visualization_msgs::MarkerArray& out);

/** \brief The pointer as a SPHERE marker of diameter 2 * radius at p. */
visualization_msgs::Marker pointerMarker(const Vec3& p, double radius, const std_msgs::Header& header,
                                         const std_msgs::ColorRGBA& color);

/**
 * \brief The contact point (a small SPHERE) and the normal (an ARROW from the point, length
 * arrowLength) when result.contact; otherwise two DELETE markers that clear them.
 */
void appendContactMarkers(const ContactResult& result, double arrowLength, const std_msgs::Header& header,
                          visualization_msgs::MarkerArray& out);

/** \brief A DELETE marker for (ns, id). */
visualization_msgs::Marker deleteMarker(const char* ns, int id, const std_msgs::Header& header);

}  // namespace clod_haptics
