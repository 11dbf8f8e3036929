// libFuzzer target: the disk cache readers on damaged files. Valid files of a small sphere mesh (the mesh with its
// adjacency, box tree and slabs; a sphere set; a grid with the detector's trees over the spheres) are written once.
// Each input picks a file (its first byte), edits it (records of a 4-byte offset and a byte to xor in; a record
// whose byte is 0 truncates the file there), then makes the checksum right again, so that the readers' own checks,
// not the checksum, must catch the damage. A read either throws FormatError or gives data that a detector and a
// swept query use: they are built and queried here, under ASan and UBSan. A sphere set that passes its checks must
// also give exact answers (fitProblem stands between a set and the detector); a grid or a mesh tree with wrong but
// well-formed contents is the checksum's to catch, so for those only memory safety and finite answers are required.

#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <memory>
#include <string>
#include <vector>

#include "clod_haptics/core/checksum.h"
#include "clod_haptics/core/errors.h"
#include "clod_haptics/core/grid_cache.h"
#include "clod_haptics/core/mesh_cache.h"
#include "clod_haptics/core/sphere_cache.h"
#include "clod_haptics/core/swept_query.h"
#include "fuzz_common.h"

namespace {

using namespace clod_haptics;

constexpr double kDistance = 0.15;  // about 40 spheres on the unit sphere below
constexpr double kRadius = 0.1;     // the grid's radius and the queries'

std::vector<char> fileBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::vector<char>((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

void writeFile(const std::string& path, const std::vector<char>& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

struct Fixture {
  std::string dir;
  std::shared_ptr<const TriangleMesh> mesh;
  std::shared_ptr<const ClodSphereSet> set;
  std::uint64_t meshKey = 0x5eed, meshHash = 0;
  GridCacheKey gridKey;
  std::vector<char> files[3];  // mesh, sphere set, grid
  std::string paths[3];
  std::vector<Vec3> probes;
};

/** A UV sphere of radius 1: 16 x 10, 288 triangles. */
TriangleMesh sphereMesh() {
  std::vector<Vec3> v{Vec3(0, 0, 1), Vec3(0, 0, -1)};
  const int around = 16, rings = 9;
  for (int i = 1; i <= rings; ++i)
    for (int j = 0; j < around; ++j) {
      const double t = M_PI * i / (rings + 1), p = 2.0 * M_PI * j / around;
      v.emplace_back(std::sin(t) * std::cos(p), std::sin(t) * std::sin(p), std::cos(t));
    }
  auto at = [&](int ring, int j) { return static_cast<std::uint32_t>(2 + (ring - 1) * around + (j % around)); };
  std::vector<Triangle> t;
  for (int j = 0; j < around; ++j) {
    t.push_back({0, at(1, j), at(1, j + 1)});
    t.push_back({1, at(rings, j + 1), at(rings, j)});
    for (int i = 1; i < rings; ++i) {
      t.push_back({at(i, j), at(i + 1, j), at(i + 1, j + 1)});
      t.push_back({at(i, j), at(i + 1, j + 1), at(i, j + 1)});
    }
  }
  return makeMesh(v, t, "sphere");
}

Fixture& fixture() {
  static Fixture f = [] {
    Fixture x;
    char pattern[] = "/tmp/clod_fuzz_cache_XXXXXX";
    x.dir = mkdtemp(pattern);
    x.mesh = std::make_shared<const TriangleMesh>(sphereMesh());
    x.set = std::make_shared<const ClodSphereSet>(ClodBuilder(x.mesh).build(kDistance));
    x.meshHash = meshContentHash(*x.mesh);
    x.gridKey.meshHash = x.meshHash;
    x.gridKey.distance = x.set->distance;
    x.gridKey.setHash = sphereSetHash(*x.set);
    x.gridKey.radius = kRadius;
    x.paths[0] = x.dir + "/mesh.clodmesh";
    x.paths[1] = x.dir + "/set.clodsph";
    x.paths[2] = x.dir + "/grid.clodgrid";
    writeMeshBinary(*x.mesh, x.meshKey, x.paths[0]);
    writeSphereSetBinary(*x.set, x.meshHash, x.paths[1]);
    writeCellGridBinary(ClodDetector::buildGridParts(*x.mesh, *x.set, kRadius), x.gridKey, x.mesh->size(), x.paths[2]);
    for (int k = 0; k < 3; ++k) x.files[k] = fileBytes(x.paths[k]);
    // Probes inside, on, near and outside the sphere, along a spiral.
    for (int i = 0; i < 24; ++i) {
      const double z = -1.0 + 2.0 * (i + 0.5) / 24, phi = 2.4 * i, s = std::sqrt(1.0 - z * z);
      const double radial = 0.85 + 0.3 * ((i * 7) % 24) / 23.0;
      x.probes.push_back(radial * Vec3(s * std::cos(phi), s * std::sin(phi), z));
    }
    return x;
  }();
  return f;
}

/** Queries and sweeps with a detector; with exact, the answers must be the brute force's. */
void exercise(const std::shared_ptr<const TriangleMesh>& mesh, const std::shared_ptr<const ClodDetector>& det,
              const std::vector<Vec3>& probes, bool exact) {
  for (const Vec3& p : probes) {
    if (exact) {
      clod_fuzz::checkQuery(*mesh, *det, p, kRadius);
      continue;
    }
    for (DetectionMode mode : {DetectionMode::Exact, DetectionMode::Spheres}) {
      for (double r : {kRadius, 0.5 * kRadius, 3.0 * kRadius}) {
        ContactResult c;
        det->query(p, r, mode, c);
        CLOD_FUZZ_CHECK(!c.contact || (std::isfinite(c.distance) && c.point.allFinite()), "non-finite contact");
      }
    }
  }
  const SweptSphereQuery swept(mesh, det);
  for (std::size_t i = 0; i + 1 < probes.size(); ++i) {
    SweptContact hit;
    swept.sweep(probes[i], probes[i + 1], kRadius, hit);
    CLOD_FUZZ_CHECK(hit.toi >= 0.0 && hit.toi <= 1.0, "time of impact %g", hit.toi);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  Fixture& f = fixture();
  if (size < 1) return 0;
  const int kind = data[0] % 3;
  std::vector<char> bytes = f.files[kind];
  for (std::size_t at = 1; at + 5 <= size && bytes.size() > 16; at += 5) {
    std::uint32_t offset;
    std::memcpy(&offset, data + at, 4);
    offset %= static_cast<std::uint32_t>(bytes.size() - 8);  // the checksum's bytes are rewritten below
    if (data[at + 4] == 0) {
      bytes.resize(offset + 8);  // truncated there (the last 8 bytes become the checksum)
      continue;
    }
    bytes[offset] = static_cast<char>(bytes[offset] ^ data[at + 4]);
  }
  if (bytes.size() >= 16) {
    const std::uint64_t sum = cacheChecksum(bytes.data(), bytes.size() - 8);
    std::memcpy(bytes.data() + bytes.size() - 8, &sum, 8);
  }
  const std::string path = f.dir + "/input." + std::to_string(kind);
  writeFile(path, bytes);
  try {
    if (kind == 0) {
      auto mesh = std::make_shared<const TriangleMesh>(readMeshBinary(path, f.meshKey));
      // A mesh that passes is a mesh: build a level over it and use its tree and slabs as read.
      auto set = std::make_shared<const ClodSphereSet>(ClodBuilder(mesh).build(kDistance * mesh->diagonal() / 2.0));
      auto det = std::make_shared<const ClodDetector>(mesh, set, FastLevel::Grid, kRadius);
      CLOD_FUZZ_CHECK(det->meshTree() == mesh->boxTree, "the tree read is the one the detector uses");
      exercise(mesh, det, f.probes, false);
    } else if (kind == 1) {
      auto set = std::make_shared<const ClodSphereSet>(readSphereSetBinary(path, f.meshHash, f.set->distance, *f.mesh));
      auto det = std::make_shared<const ClodDetector>(f.mesh, set, FastLevel::Grid, kRadius);
      exercise(f.mesh, det, f.probes, true);
    } else {
      ClodDetector::GridParts parts = readCellGridBinary(path, f.gridKey, *f.mesh, *f.set);
      auto det = std::make_shared<const ClodDetector>(f.mesh, f.set, FastLevel::Grid, kRadius,
                                                      [&](double) { return std::move(parts); });
      exercise(f.mesh, det, f.probes, false);
    }
  } catch (const FormatError&) {
    // A damaged file refused, typed: what the cache wants (it deletes the file and builds again).
  } catch (const ClodError& e) {
    // Only the level built over a mesh read from a damaged file may refuse it (say, coordinates so large that its
    // size overflows): the readers themselves throw FormatError, and a set that passed must fit.
    CLOD_FUZZ_CHECK(kind == 0, "%s", e.what());
  }
  return 0;
}
