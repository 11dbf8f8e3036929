// Embree 3 peer: rtcPointQuery with the pointer radius as its bound (padded for Embree's float
// BVH); the callback computes the closest point in double and shrinks the radius as it goes.
#include <embree3/rtcore.h>

#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>

#include "bench_common.h"
#include "clod_haptics/core/geometry.h"

namespace clod_bench {
namespace {

struct Search {
  const TriangleMesh* mesh;
  Vec3 p;
  double best2;  // r^2, then the best squared distance
  std::int32_t triangle = -1;
  Vec3 point;
};

bool visit(RTCPointQueryFunctionArguments* args) {
  Search& s = *static_cast<Search*>(args->userPtr);
  const unsigned t = args->primID;
  const Vec3 q = clod_haptics::closestPointOnTriangle(s.p, s.mesh->vertex(t, 0), s.mesh->vertex(t, 1), s.mesh->vertex(t, 2));
  const double d2 = (q - s.p).squaredNorm();
  if (d2 < s.best2 || (d2 == s.best2 && (s.triangle < 0 || static_cast<std::int32_t>(t) < s.triangle))) {
    s.best2 = d2;
    s.triangle = static_cast<std::int32_t>(t);
    s.point = q;
    // Shrink the float search radius, padded so float rounding never drops a closer triangle.
    args->query->radius = static_cast<float>(std::sqrt(d2) * (1.0 + 1e-5) + 1e-6);
    return true;
  }
  return false;
}

class EmbreePeer : public Peer {
 public:
  EmbreePeer(const TriangleMesh& mesh, int threads) : mesh_(mesh) {
    const auto t0 = std::chrono::steady_clock::now();
    device_ = rtcNewDevice(("threads=" + std::to_string(threads)).c_str());
    if (!device_) throw std::runtime_error("embree: rtcNewDevice failed");
    scene_ = rtcNewScene(device_);
    rtcSetSceneBuildQuality(scene_, RTC_BUILD_QUALITY_HIGH);
    RTCGeometry geometry = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_TRIANGLE);
    float* v = static_cast<float*>(rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                           3 * sizeof(float), mesh.vertices.size()));
    for (std::size_t i = 0; i < mesh.vertices.size(); ++i)
      for (int k = 0; k < 3; ++k) v[3 * i + k] = static_cast<float>(mesh.vertices[i][k]);
    unsigned* idx = static_cast<unsigned*>(rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                                   3 * sizeof(unsigned), mesh.size()));
    for (std::size_t t = 0; t < mesh.size(); ++t)
      for (int k = 0; k < 3; ++k) idx[3 * t + k] = mesh.triangles[t][k];
    rtcCommitGeometry(geometry);
    rtcAttachGeometry(scene_, geometry);
    rtcReleaseGeometry(geometry);
    const auto c0 = std::chrono::steady_clock::now();
    rtcCommitScene(scene_);
    indexMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - c0).count();
    buildMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  }
  ~EmbreePeer() override {
    rtcReleaseScene(scene_);
    rtcReleaseDevice(device_);
  }
  std::string name() const override { return "embree"; }
  void query(const Vec3& p, double r, Answer& out) const override {
    Search s{&mesh_, p, r * r, -1, Vec3::Zero()};
    RTCPointQuery q;
    q.x = static_cast<float>(p.x());
    q.y = static_cast<float>(p.y());
    q.z = static_cast<float>(p.z());
    q.time = 0.f;
    q.radius = static_cast<float>(r * (1.0 + 1e-5) + 1e-6);
    RTCPointQueryContext context;
    rtcInitPointQueryContext(&context);
    rtcPointQuery(scene_, &q, &context, visit, &s);
    out.contact = s.triangle >= 0;
    if (out.contact) {
      out.point = s.point;
      out.distance = std::sqrt(s.best2);
      out.triangle = s.triangle;
    }
  }

 private:
  const TriangleMesh& mesh_;
  RTCDevice device_;
  RTCScene scene_;
};

}  // namespace

std::unique_ptr<Peer> makeEmbreePeer(const TriangleMesh& mesh, int threads) {
  return std::make_unique<EmbreePeer>(mesh, threads);
}

}  // namespace clod_bench
