// FCL 0.7 peer: distance of a zero-radius sphere at p to a BVHModel<OBBRSS>, with the result's
// min_distance initialised to r so the traversal prunes everything farther (FCL with Sphered(r)
// leaves the distance unset when the ball overlaps the mesh, so the radius goes into the bound).
#include <fcl/geometry/bvh/BVH_model.h>
#include <fcl/geometry/shape/sphere.h>
#include <fcl/narrowphase/collision_object.h>
#include <fcl/narrowphase/distance.h>

#include <chrono>
#include <cmath>

#include "bench_common.h"

namespace clod_bench {
namespace {

class FclPeer : public Peer {
 public:
  explicit FclPeer(const TriangleMesh& mesh) {
    const auto t0 = std::chrono::steady_clock::now();
    auto model = std::make_shared<fcl::BVHModel<fcl::OBBRSSd>>();
    std::vector<fcl::Vector3d> vertices(mesh.vertices.begin(), mesh.vertices.end());
    std::vector<fcl::Triangle> triangles;
    triangles.reserve(mesh.size());
    for (const auto& t : mesh.triangles) triangles.emplace_back(t[0], t[1], t[2]);
    model->beginModel(static_cast<int>(triangles.size()), static_cast<int>(vertices.size()));
    model->addSubModel(vertices, triangles);
    model->endModel();
    meshObject_ = std::make_unique<fcl::CollisionObjectd>(model);
    pointer_ = std::make_unique<fcl::CollisionObjectd>(std::make_shared<fcl::Sphered>(0.0));
    request_.enable_nearest_points = true;
    buildMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  }
  std::string name() const override { return "fcl"; }
  void query(const Vec3& p, double r, Answer& out) const override {
    pointer_->setTranslation(p);
    pointer_->computeAABB();
    fcl::DistanceResultd result;
    result.min_distance = r;
    fcl::distance(meshObject_.get(), pointer_.get(), request_, result);
    out.contact = result.b1 != fcl::DistanceResultd::NONE && result.min_distance <= r;
    if (out.contact) {
      out.point = result.nearest_points[0];
      out.distance = result.min_distance;
      out.triangle = static_cast<std::int32_t>(result.b1);
    }
  }

 private:
  std::unique_ptr<fcl::CollisionObjectd> meshObject_;
  mutable std::unique_ptr<fcl::CollisionObjectd> pointer_;  // moved per query; not thread-safe (bench only)
  fcl::DistanceRequestd request_;
};

}  // namespace

std::unique_ptr<Peer> makeFclPeer(const TriangleMesh& mesh) { return std::make_unique<FclPeer>(mesh); }

}  // namespace clod_bench
