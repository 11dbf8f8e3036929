// thin_bench: tightness of sphere sets on thin parts (generated plates, cylinders, branches, legs) and on the shared
// meshes, at the same sphere count: the tight clustering (ClodBuilder::buildAtMost on TightClustering), a
// Hubbard-like medial reference (medial_reference.h) and an octree (tightness.h); also the tight clustering
// without splitting long triangles (every triangle whole in one sphere). Surface coverage by sampling,
// outside volume by Monte Carlo (relative to the mesh volume), build time. Writes thin_tightness.csv and, for the
// pictures, thin_spheres.csv (the spheres of the plates and legs models at 150).
//
// usage: thin_bench --shared DIR --out DIR [--quick] [--only NAME[,NAME...]]
//   --only: just the models named (generated ones by name, shared ones by file name), their spheres dumped too.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "clod_haptics/core/clustering.h"
#include "clod_haptics/core/mesh_loader.h"
#include "clod_haptics/core/sphere_placement.h"
#include "clod_haptics/core/sphere_set.h"
#include "clod_haptics/core/tight_clustering.h"
#include "medial_reference.h"
#include "thin_models.h"
#include "tightness.h"

namespace fs = std::filesystem;
using namespace clod_haptics;
using namespace clod_bench;

namespace {

double msSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

struct Measure {
  double coverage = 0, outside = 0, unionVolume = 0;
};

// Outside volume: points uniform in the union (a sphere by volume, a point in it, weight 1 / spheres holding it),
// the share outside the mesh by its inside test; coverage: the share of surface samples inside some sphere.
Measure measure(const SphereList& s, const InsideTest& inside, const std::vector<Vec3>& surface, double meshVolume,
                std::size_t samples, std::uint64_t seed) {
  Measure m;
  const SphereGrid grid(s);
  std::size_t covered = 0;
  for (const Vec3& p : surface) covered += grid.contains(p);
  m.coverage = static_cast<double>(covered) / surface.size();
  std::vector<double> cumulative(s.radii.size());
  double total = 0;
  for (std::size_t i = 0; i < cumulative.size(); ++i) cumulative[i] = total += 4.0 / 3.0 * M_PI * std::pow(s.radii[i], 3);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  double unionSum = 0, outsideSum = 0;
  for (std::size_t j = 0; j < samples; ++j) {
    const std::size_t i = std::min<std::size_t>(
        cumulative.size() - 1, std::lower_bound(cumulative.begin(), cumulative.end(), unit(rng) * total) - cumulative.begin());
    Vec3 u;
    do u = Vec3(2 * unit(rng) - 1, 2 * unit(rng) - 1, 2 * unit(rng) - 1);
    while (u.squaredNorm() > 1.0);
    const Vec3 p = s.centres[i] + s.radii[i] * u;
    const double w = 1.0 / std::max<std::size_t>(1, grid.count(p));
    unionSum += w;
    if (!inside.inside(p)) outsideSum += w;
  }
  m.unionVolume = total * unionSum / samples / meshVolume;
  m.outside = total * outsideSum / samples / meshVolume;
  return m;
}

// Monte Carlo volume of the mesh by its own inside test, in its bounding box.
double mcVolume(const TriangleMesh& mesh, const InsideTest& inside, std::size_t samples) {
  const Eigen::AlignedBox3d b = mesh.bounds();
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::size_t in = 0;
  for (std::size_t j = 0; j < samples; ++j)
    in += inside.inside(b.min() + Vec3(unit(rng), unit(rng), unit(rng)).cwiseProduct(b.sizes()));
  return b.volume() * in / samples;
}

SphereList listOf(const ClodSphereSet& set) { return {set.centres, set.radii}; }

void dumpSpheres(std::ofstream& out, const std::string& model, const std::string& kind, const SphereList& s) {
  for (std::size_t i = 0; i < s.radii.size(); ++i)
    out << model << ',' << kind << ',' << s.centres[i].x() << ',' << s.centres[i].y() << ',' << s.centres[i].z() << ','
        << s.radii[i] << '\n';
}

}  // namespace

int main(int argc, char** argv) {
  std::string shared, out;
  bool quick = false;
  std::vector<std::string> only;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--shared" && i + 1 < argc) shared = argv[++i];
    else if (a == "--out" && i + 1 < argc) out = argv[++i];
    else if (a == "--quick") quick = true;
    else if (a == "--only" && i + 1 < argc) {
      std::stringstream names(argv[++i]);
      for (std::string name; std::getline(names, name, ',');) only.push_back(name);
    } else {
      std::cerr << "usage: thin_bench --shared DIR --out DIR [--quick] [--only NAME[,NAME...]]\n";
      return 2;
    }
  }
  if (out.empty()) {
    std::cerr << "thin_bench: --out is required\n";
    return 2;
  }
  fs::create_directories(out);
  const std::size_t mcSamples = quick ? 30000 : 200000, surfaceCount = quick ? 30000 : 200000;
  const std::size_t medialSamples = quick ? 8000 : 20000;

  std::vector<ThinModel> models = thinModels();
  if (!shared.empty()) {
    std::vector<std::string> paths;
    for (const auto& e : fs::directory_iterator(fs::path(shared) / "data" / "meshes"))
      if (e.path().extension() == ".off") paths.push_back(e.path().string());
    std::sort(paths.begin(), paths.end());
    for (const std::string& p : paths) {
      MeshLoadOptions o;
      o.normalize = true;
      TriangleMesh m = loadMesh(p, o);
      if (m.size() < 1000) continue;  // the fixtures (8 triangles, a sheet with a border) hold no volume to compare
      models.push_back({fs::path(p).filename().string(), "shared mesh, normalised", std::move(m)});
    }
  }
  if (!only.empty()) {
    for (const std::string& name : only)
      if (std::none_of(models.begin(), models.end(), [&](const ThinModel& m) { return m.name == name; })) {
        std::cerr << "thin_bench: no model named " << name << "\n";
        return 2;
      }
    models.erase(
        std::remove_if(models.begin(), models.end(),
                       [&](const ThinModel& m) { return std::find(only.begin(), only.end(), m.name) == only.end(); }),
        models.end());
  }
  std::ofstream csv(out + "/thin_tightness.csv"), spheres(out + "/thin_spheres.csv");
  csv << "model,triangles,description,target,kind,spheres,d,build_ms,surface_covered,outside_volume_rel,"
         "union_volume_rel,outside_vs_medial\n";
  spheres << "model,kind,x,y,z,r\n";
  for (const ThinModel& model : models) {
    const auto mesh = std::make_shared<const TriangleMesh>(model.mesh);
    const InsideTest inside(*mesh);
    const double volume = std::abs(mcVolume(*mesh, inside, mcSamples));
    std::vector<Vec3> surface;
    surfaceSamples(*mesh, surfaceCount, 99, surface, nullptr);
    for (std::size_t target : {std::size_t{150}, std::size_t{500}}) {
      const SphereList medial = medialSpheres(*mesh, target, medialSamples, 7);
      const std::size_t n = medial.radii.size();
      // The reference grown to cover the surface: four times as many samples of their own, not the ones coverage is
      // measured on.
      const SphereList grown = grownToCover(medial, *mesh, 4 * surfaceCount, 98);
      // Ours at no more spheres than the reference: the least d with at most n spheres; its build time as a user
      // pays it (placement, then one build at that d), the best of three.
      const ClodBuilder tightBuilder(mesh, std::make_shared<PaperPlacement>(), makeClustering("tight"));
      const ClodSphereSet tight = tightBuilder.buildAtMost(n);
      double tightMs = INFINITY;
      for (int run = 0; run < 3; ++run) {
        const auto t0 = std::chrono::steady_clock::now();
        const ClodBuilder fresh(mesh, std::make_shared<PaperPlacement>(), makeClustering("tight"));
        fresh.build(tight.distance);
        tightMs = std::min(tightMs, msSince(t0));
      }
      // The same strategy holding every triangle whole in one sphere (no pieces), for what splitting gives.
      const ClodBuilder wholeBuilder(mesh, std::make_shared<PaperPlacement>(), std::make_shared<TightClustering>(0.0));
      const ClodSphereSet whole = wholeBuilder.buildAtMost(n);
      const ClodBuilder linkBuilder(mesh);
      const ClodSphereSet link = linkBuilder.buildAtMost(n);
      int depth = 0;
      const SphereList octree = octreeSpheres(*mesh, n, depth);
      const Measure mm = measure(medial, inside, surface, volume, mcSamples, 1);
      struct Row {
        const char* kind;
        SphereList s;
        double d, ms;
      };
      for (const Row& r : {Row{"medial-reference", medial, NAN, NAN}, Row{"medial-grown", grown, NAN, NAN},
                           Row{"clod-tight", listOf(tight), tight.distance, tightMs},
                           Row{"clod-tight-whole", listOf(whole), whole.distance, NAN},
                           Row{"clod-single-link", listOf(link), link.distance, NAN}, Row{"octree", octree, NAN, NAN}}) {
        const Measure m = measure(r.s, inside, surface, volume, mcSamples, 1);
        csv << model.name << ',' << mesh->size() << ",\"" << model.description << "\"," << target << ',' << r.kind << ','
            << r.s.radii.size() << ',' << r.d << ',' << r.ms << ',' << m.coverage << ',' << m.outside << ','
            << m.unionVolume << ',' << m.outside / mm.outside << '\n';
        std::cout << model.name << " (" << mesh->size() << " triangles) " << r.kind << ": " << r.s.radii.size()
                  << " spheres, covered " << m.coverage << ", outside " << m.outside << " (" << m.outside / mm.outside
                  << " x medial)" << (std::isfinite(r.ms) ? ", build " + std::to_string(r.ms) + " ms" : "") << "\n"
                  << std::flush;
        if (!only.empty())
          dumpSpheres(spheres, model.name, std::string(r.kind) + "@" + std::to_string(target), r.s);
        else if (target == 150 && (model.name == "plate-0.005" || model.name == "plate-0.03-long" ||
                                   model.name == "plate-0.015-mixed" || model.name == "legs"))
          dumpSpheres(spheres, model.name, r.kind, r.s);
      }
    }
  }
  return 0;
}
