// libFuzzer target: mesh parsing (assimp through loadMesh) plus building and a few queries.
// The first byte picks the file extension (.off, .obj, .stl, .ply) and the options; the rest is the
// file's content, written to a temporary file. Load errors must be typed (ClodError); a loaded mesh
// must build a covering sphere set and answer queries like brute force.

#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <fstream>
#include <string>

#include "clod_haptics/core/errors.h"
#include "clod_haptics/core/mesh_loader.h"
#include "clod_haptics/core/probes.h"
#include "fuzz_common.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace clod_haptics;
  if (size < 1) return 0;
  static const char* kExt[] = {".off", ".obj", ".stl", ".ply"};
  const std::uint8_t selector = data[0];
  const std::string path = "/tmp/clod_fuzz_mesh_" + std::to_string(::getpid()) + kExt[selector % 4];
  {
    std::ofstream out(path, std::ios::binary);
    out.write(reinterpret_cast<const char*>(data + 1), static_cast<std::streamsize>(size - 1));
  }
  MeshLoadOptions options;
  options.normalize = (selector & 4) != 0;
  options.scale = (selector & 8) ? 1e3 : 1.0;
  std::shared_ptr<TriangleMesh> mesh;
  try {
    mesh = std::make_shared<TriangleMesh>(loadMesh(path, options));
  } catch (const ClodError&) {
    std::remove(path.c_str());
    return 0;  // a typed error is the expected answer to bad input
  }
  std::remove(path.c_str());
  if (mesh->size() > 3000) return 0;  // keep each run fast; brute force below is O(n) per probe
  for (const Vec3& v : mesh->vertices) CLOD_FUZZ_CHECK(v.allFinite(), "non-finite vertex after load");
  for (const Vec3& n : mesh->normals) CLOD_FUZZ_CHECK(n.allFinite(), "non-finite normal after load");
  const double size0 = mesh->diagonal();
  if (!std::isfinite(size0)) return 0;
  const ClodBuilder builder(mesh, std::make_shared<PaperPlacement>(1));
  const double d = size0 * 0.01 * ((selector >> 4) & 7);
  const auto set = std::make_shared<const ClodSphereSet>(builder.build(d));
  clod_fuzz::checkSet(*mesh, *set);
  const ClodDetector det(mesh, set);
  const double r = 0.01 * size0;
  for (const Vec3& p : nearSurfaceProbes(*mesh, 16, 2 * r, size)) clod_fuzz::checkQuery(*mesh, det, p, r);
  for (const Vec3& v : mesh->vertices) {
    clod_fuzz::checkQuery(*mesh, det, v, 0.0);
    if (&v - mesh->vertices.data() > 16) break;
  }
  return 0;
}
