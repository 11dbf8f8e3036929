#pragma once
// The proxy section of clod_bench: the god-object proxy (HapticRenderer) beside the penalty model.

#include <string>
#include <vector>

#include "clod_haptics/core/mesh.h"

namespace clod_bench {

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
