#include "clod_haptics/core/scene_assets.h"

#include <chrono>
#include <iterator>
#include <sstream>

#include "binary_io.h"
#include "clod_haptics/core/errors.h"

namespace clod_haptics {

SceneAssets::SceneAssets(std::shared_ptr<SphereSetCache> cache, FastLevel fastLevel, double gridRadius,
                         bool keepBuilders, std::shared_ptr<const Clustering> clustering)
    : cache_(std::move(cache)),
      gridCache_(cache_ ? std::make_shared<CellGridCache>(cache_->directory()) : nullptr),
      clustering_(clustering ? std::move(clustering) : std::make_shared<const SingleLinkClustering>()),
      fastLevel_(fastLevel),
      gridRadius_(gridRadius),
      keepBuilders_(keepBuilders) {}

void SceneAssets::setRemote(RemoteSource remote) {
  std::lock_guard<std::mutex> lock(mutex_);
  remote_ = std::move(remote);
}

void SceneAssets::setMeshCache(std::shared_ptr<MeshCache> meshCache) {
  std::lock_guard<std::mutex> lock(mutex_);
  meshCache_ = std::move(meshCache);
}

std::shared_ptr<const TriangleMesh> SceneAssets::mesh(const std::string& path, const MeshLoadOptions& options,
                                                      MeshInfo* info) {
  std::ostringstream key;
  key.precision(17);
  key << path << '|' << options.scale << '|' << options.normalize << '|' << options.orientOutward;
  MeshInfo local;
  MeshInfo& out = info ? *info : local;
  out = MeshInfo();
  std::lock_guard<std::mutex> lock(mutex_);
  auto& slot = meshes_[key.str()];
  if (slot) {
    out.shared = true;
    out.cache.source = CacheSource::Hit;
    return slot;
  }
  try {
    slot = std::make_shared<const TriangleMesh>(meshCache_ ? meshCache_->load(path, options, &out.cache)
                                                           : loadMesh(path, options));
  } catch (...) {
    meshes_.erase(key.str());
    throw;
  }
  return slot;
}

std::uint64_t SceneAssets::hash(const std::shared_ptr<const TriangleMesh>& mesh) {
  std::lock_guard<std::mutex> lock(mutex_);
  return hashLocked(mesh);
}

std::uint64_t SceneAssets::hashLocked(const std::shared_ptr<const TriangleMesh>& mesh) {
  auto it = hashes_.find(mesh.get());
  if (it != hashes_.end() && it->second.first.lock() == mesh) return it->second.second;
  const std::uint64_t h = meshContentHash(*mesh);
  hashes_[mesh.get()] = {mesh, h};
  return h;
}

std::shared_ptr<const ClodSphereSet> SceneAssets::spheresLocked(const std::shared_ptr<const TriangleMesh>& mesh,
                                                                double distance, LevelInfo& out) {
  const LevelKey key{mesh.get(), detail::bitsOf(distance)};
  auto knownSet = sets_.find(key);
  if (knownSet != sets_.end() && knownSet->second.first.lock() == mesh) {
    out.shared = true;
    out.cache.source = CacheSource::Hit;
    return knownSet->second.second;
  }
  const std::uint64_t h = hashLocked(mesh);
  dropUnusedLevels(mesh.get(), key.second);
  std::shared_ptr<const ClodSphereSet> set;
  if (cache_) {
    set = cache_->getOrBuild(
        *mesh, h, distance, [&] { return fetchOrBuild(mesh, h, distance, out); }, &out.cache);
  } else {
    const auto start = std::chrono::steady_clock::now();
    set = std::make_shared<const ClodSphereSet>(fetchOrBuild(mesh, h, distance, out));
    out.cache.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  }
  sets_[key] = {mesh, set};
  return set;
}

ClodSphereSet SceneAssets::fetchOrBuild(const std::shared_ptr<const TriangleMesh>& mesh, std::uint64_t hash,
                                        double distance, LevelInfo& out) {
  if (remote_) {
    std::string why;
    std::shared_ptr<const ClodSphereSet> fetched = remote_(*mesh, distance, why);
    if (fetched) {
      why = fitProblem(*mesh, *fetched);
      if (why.empty()) {
        out.remote = true;
        return *fetched;
      }
      why = "the remote set does not fit the mesh: " + why;
    }
    out.remoteProblem = why;
  }
  std::shared_ptr<const ClodBuilder> use = builders_[hash];
  if (!use) {
    use = std::make_shared<const ClodBuilder>(mesh, std::make_shared<PaperPlacement>(), clustering_);
    ++placements_;
    if (keepBuilders_) builders_[hash] = use;
  }
  if (!keepBuilders_) builders_.erase(hash);
  return use->build(distance);
}

void SceneAssets::dropUnusedLevels(const TriangleMesh* mesh, std::uint64_t keepDistanceBits) {
  // Entries only this map holds, of the same mesh at another distance: nothing would share them again soon.
  for (auto it = levels_.begin(); it != levels_.end();) {
    const bool drop = std::get<0>(it->first).first == mesh && std::get<0>(it->first).second != keepDistanceBits &&
                      it->second.use_count() == 1;
    it = drop ? levels_.erase(it) : std::next(it);
  }
  for (auto it = sets_.begin(); it != sets_.end();) {
    const bool drop =
        it->first.first == mesh && it->first.second != keepDistanceBits && it->second.second.use_count() == 1;
    it = drop ? sets_.erase(it) : std::next(it);
  }
}

namespace {
double normalisedDistance(const std::shared_ptr<const TriangleMesh>& mesh, double distance, const char* what) {
  if (!mesh) throw InvalidParameter(std::string(what) + ": no mesh");
  requireNonNegative(distance, "clustering distance");
  return distance == 0.0 ? 0.0 : distance;  // -0 and +0 are the same level
}
}  // namespace

std::shared_ptr<const ClodSphereSet> SceneAssets::spheres(const std::shared_ptr<const TriangleMesh>& mesh,
                                                          double distance, LevelInfo* info) {
  distance = normalisedDistance(mesh, distance, "SceneAssets::spheres");
  LevelInfo local;
  LevelInfo& out = info ? *info : local;
  out = LevelInfo();
  std::lock_guard<std::mutex> lock(mutex_);
  return spheresLocked(mesh, distance, out);
}

GridCacheKey SceneAssets::gridKeyLocked(const std::shared_ptr<const TriangleMesh>& mesh, double distance,
                                        const ClodSphereSet& set, double radius) {
  GridCacheKey key;
  key.meshHash = hashLocked(mesh);
  key.distance = distance;
  key.setHash = sphereSetHash(set);
  key.radius = radius;
  return key;
}

bool SceneAssets::gridCached(const std::shared_ptr<const TriangleMesh>& mesh, double distance) {
  distance = normalisedDistance(mesh, distance, "SceneAssets::gridCached");
  LevelInfo out;
  std::lock_guard<std::mutex> lock(mutex_);
  if (!gridCache_ || fastLevel_ != FastLevel::Grid) return false;
  const auto set = spheresLocked(mesh, distance, out);
  const double radius = ClodDetector::effectiveGridRadius(*mesh, gridRadius_);
  return radius > 0.0 && gridCache_->has(gridKeyLocked(mesh, distance, *set, radius));
}

std::shared_ptr<const ClodDetector> SceneAssets::level(const std::shared_ptr<const TriangleMesh>& mesh, double distance,
                                                       FastLevel fastLevel, LevelInfo* info) {
  distance = normalisedDistance(mesh, distance, "SceneAssets::level");
  LevelInfo local;
  LevelInfo& out = info ? *info : local;
  out = LevelInfo();
  const LevelKey key{mesh.get(), detail::bitsOf(distance)};

  std::lock_guard<std::mutex> lock(mutex_);
  const double gridRadius = fastLevel == FastLevel::Grid ? gridRadius_ : 0.0;
  const std::uint64_t radiusBits = detail::bitsOf(gridRadius);
  // Keyed by the mesh object (which the detector and set keep alive), so the detector handed out
  // always refers to the very mesh the caller passed: SceneDetector checks that.
  auto found = levels_.find({key, fastLevel, radiusBits});
  if (found != levels_.end()) {
    out.shared = true;
    out.cache.source = CacheSource::Hit;
    return found->second;
  }
  // Another level's Grid detector of this mesh for the same radius (taken before the set's build may drop unused
  // levels): its grid's candidates are this level's too, so the new grid is made from it (CellGrid::forLevel: a change
  // of d while touching waits for the clustering and a pass over the candidates, not a whole grid build).
  std::shared_ptr<const ClodDetector> sibling;
  if (fastLevel == FastLevel::Grid)
    for (const auto& entry : levels_)
      if (std::get<0>(entry.first).first == mesh.get() && std::get<1>(entry.first) == fastLevel &&
          std::get<2>(entry.first) == radiusBits && entry.second->mesh() == mesh && !entry.second->grid().empty()) {
        sibling = entry.second;
        break;
      }
  auto set = spheresLocked(mesh, distance, out);
  const auto start = std::chrono::steady_clock::now();
  const CellGrid* sameMesh = sibling ? &sibling->grid() : nullptr;
  auto build = [&](double radius) {
    return ClodDetector::buildGridParts(*mesh, *set, radius, sameMesh, &out.gridFromLevel);
  };
  ClodDetector::GridSource gridSource;
  if (gridCache_ && fastLevel == FastLevel::Grid) {
    gridSource = [&](double radius) {
      return gridCache_->getOrBuild(
          *mesh, *set, gridKeyLocked(mesh, distance, *set, radius), [&] { return build(radius); }, &out.grid);
    };
  } else if (sameMesh) {
    gridSource = build;
  }
  auto detector = std::make_shared<const ClodDetector>(mesh, set, fastLevel, gridRadius, gridSource);
  out.detectorMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  // Grids of the same level for another radius that only this map holds: a radius change left them behind.
  for (auto it = levels_.begin(); it != levels_.end();) {
    const bool drop = std::get<0>(it->first) == key && std::get<1>(it->first) == fastLevel &&
                      std::get<2>(it->first) != radiusBits && it->second.use_count() == 1;
    it = drop ? levels_.erase(it) : std::next(it);
  }
  levels_[{key, fastLevel, radiusBits}] = detector;
  return detector;
}

void SceneAssets::setGridRadius(double radius) {
  requireNonNegative(radius, "grid radius");
  std::lock_guard<std::mutex> lock(mutex_);
  gridRadius_ = radius;
}

double SceneAssets::gridRadius() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return gridRadius_;
}

}  // namespace clod_haptics
