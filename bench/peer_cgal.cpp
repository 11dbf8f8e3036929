// CGAL 5 AABB_tree peer: closest_point_and_primitive(p, hint) with the hint at distance r, which
// bounds the search to the pointer's radius. Its own translation unit: CGAL compiles once.
#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Simple_cartesian.h>

#include <chrono>
#include <cmath>

#include "bench_common.h"

namespace clod_bench {
namespace {

using K = CGAL::Simple_cartesian<double>;
using Triangles = std::vector<K::Triangle_3>;
using Primitive = CGAL::AABB_triangle_primitive<K, Triangles::const_iterator>;
using Traits = CGAL::AABB_traits<K, Primitive>;
using Tree = CGAL::AABB_tree<Traits>;

class CgalPeer : public Peer {
 public:
  explicit CgalPeer(const TriangleMesh& mesh) {
    const auto t0 = std::chrono::steady_clock::now();
    triangles_.reserve(mesh.size());
    for (std::size_t t = 0; t < mesh.size(); ++t) {
      const Vec3 &a = mesh.vertex(t, 0), &b = mesh.vertex(t, 1), &c = mesh.vertex(t, 2);
      triangles_.emplace_back(K::Point_3(a.x(), a.y(), a.z()), K::Point_3(b.x(), b.y(), b.z()),
                              K::Point_3(c.x(), c.y(), c.z()));
    }
    const auto i0 = std::chrono::steady_clock::now();
    tree_.insert(triangles_.cbegin(), triangles_.cend());
    tree_.build();
    tree_.accelerate_distance_queries();
    // One query builds the lazily constructed search structures before the timing.
    tree_.closest_point(K::Point_3(0, 0, 0));
    indexMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - i0).count();
    buildMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  }
  std::string name() const override { return "cgal"; }
  void query(const Vec3& p, double r, Answer& out) const override {
    // The hint: a point at distance r (padded by 1e-9 relative so a triangle at exactly r is found).
    const double reach = r * (1.0 + 1e-9);
    const K::Point_3 hintPoint(p.x() + reach, p.y(), p.z());
    const Tree::Point_and_primitive_id hint(hintPoint, triangles_.cbegin());
    const Tree::Point_and_primitive_id found = tree_.closest_point_and_primitive(K::Point_3(p.x(), p.y(), p.z()), hint);
    const Vec3 q(found.first.x(), found.first.y(), found.first.z());
    const double d2 = (q - p).squaredNorm();
    if (found.first == hintPoint || !(d2 <= r * r)) {
      out.contact = false;
      return;
    }
    out.contact = true;
    out.point = q;
    out.distance = std::sqrt(d2);
    out.triangle = static_cast<std::int32_t>(found.second - triangles_.cbegin());
  }

 private:
  Triangles triangles_;
  Tree tree_;
};

}  // namespace

std::unique_ptr<Peer> makeCgalPeer(const TriangleMesh& mesh) { return std::make_unique<CgalPeer>(mesh); }

}  // namespace clod_bench
