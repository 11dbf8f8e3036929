#pragma once
// Thin-part models for the tightness benchmark (thin_bench): plates 0.005 to 0.03 thick, thin cylinders, branching
// shapes and legged bodies (insect: held out, added after the tight sets' rings were tuned), with a mix of long and
// small triangles. Deterministic; closed surfaces (a model made of
// several parts is their overlapping union, each part closed and outward wound).

#include <string>
#include <vector>

#include "clod_haptics/core/mesh.h"

namespace clod_bench {

/** \brief One generated model and what it is made of. */
struct ThinModel {
  std::string name;
  std::string description;
  clod_haptics::TriangleMesh mesh;
};

/** \brief The models of the thin-part table, in a fixed order. */
std::vector<ThinModel> thinModels();

}  // namespace clod_bench
