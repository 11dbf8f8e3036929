#pragma once
// The proxy section of clod_bench: the god-object proxy (HapticRenderer) beside the penalty model.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "clod_haptics/core/detector.h"
#include "clod_haptics/core/haptic_renderer.h"
#include "clod_haptics/core/mesh.h"
#include "clod_haptics/core/swept_scene.h"

namespace clod_bench {

/** \brief A model of the proxy section with everything both force models need (metres, at the stylus scale). */
struct Model {
  std::string name, kind;  ///< kind: plate, cylinder, antler, fine (an ellipsoid finer than r), shared
  double sizeMm = 0.0;     ///< plate thickness or cylinder diameter; 0 for the shared meshes
  std::shared_ptr<const clod_haptics::TriangleMesh> mesh;
  std::shared_ptr<const clod_haptics::ClodDetector> detector;  ///< grid level at d = 0.003 (the launch file's)
  clod_haptics::SweptScene scene;                              ///< the mesh alone, for the proxy
};

/** \brief A model from a mesh (its level, detector and scene built as the section builds them). */
std::unique_ptr<Model> prepare(std::string name, std::string kind, double sizeMm, clod_haptics::TriangleMesh mesh);
/** \brief A shared mesh file, normalised and scaled to 15 cm. */
std::unique_ptr<Model> sharedModel(const std::string& path);
/**
 * \brief The same scaled to size (m) instead, named "file@Nmm" (the section also runs every shared mesh at 4 cm, where
 * its triangles are smaller than the stylus: a tooth or a figurine at the scale of the hand).
 */
std::unique_ptr<Model> sharedModel(const std::string& path, double size);
/** \brief The section's ellipsoid of semi-axes 15, 12 and 9 mm with edges of edge r (0.25 and 0.1 in the section). */
std::unique_ptr<Model> fineEllipsoid(double edge);
/** \brief The generated thin parts of the section: plates, cylinders, the antler and the two fine ellipsoids. */
std::vector<std::unique_ptr<Model>> thinModels();
/** \brief runs straight pushes 30 mm long through the part at speed (m/s), one device point per 1 ms tick. */
std::vector<std::vector<clod_haptics::Vec3>> pushes(const Model& m, double speed, int runs, std::uint64_t seed);
/** \brief path from its first point clear of the model on (the shipped node starts its proxy there). */
std::vector<clod_haptics::Vec3> fromFreeSpace(const Model& m, const std::vector<clod_haptics::Vec3>& path);
/** \brief The shipped stylus's proxy: r = 2 mm, 400 N/m, no friction, no clamp. */
clod_haptics::ProxyParameters stylus();
/** \brief The same stylus with friction as a user turns it on (mu_static 0.5, mu_dynamic 0.4: a rubbery surface). */
clod_haptics::ProxyParameters frictionStylus();

/**
 * \brief The proxy section, at the stylus scale (r = 2 mm, 400 N/m, 1 kHz): per-tick cost of the proxy, the
 * penalty model and one point query (median, p99, max) on the shared meshes scaled to 15 cm, over straight
 * pushes through their surface at several speeds and over the recorded trajectory; and, for both force models,
 * the ticks whose force pushes the stylus on through the part, the runs with any, the largest force jump
 * between two ticks and the ticks the proxy ended inside, on generated thin parts (plates 0.5 to 5 mm, thin
 * cylinders, an antler-like branching shape) and on the shared meshes. Writes proxy_cost.csv, proxy_thin.csv
 * and proxy.md to outDir.
 */
void proxySection(const std::vector<std::string>& sharedPaths, const std::string& outDir, bool quick,
                  const std::vector<clod_haptics::Vec3>& trajectory);

}  // namespace clod_bench
