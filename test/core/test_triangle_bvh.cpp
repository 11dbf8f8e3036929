// TriangleBvh::forEachRayHit against every triangle tested with rayTriangle: the same hits, the same t.

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <map>
#include <random>

#include "clod_haptics/core/geometry.h"
#include "clod_haptics/core/probes.h"
#include "clod_haptics/core/triangle_bvh.h"
#include "simd/dispatch.h"
#include "simd/packet_avx2.h"
#include "test_helpers.h"

namespace {

using namespace clod_haptics;

void checkRays(const TriangleMesh& mesh, int rays, std::uint64_t seed, unsigned threads = 1) {
  const TriangleBvh bvh(mesh, 4, threads);
  ASSERT_FALSE(bvh.nodes().empty());
  std::vector<std::uint32_t> order = bvh.order();
  std::sort(order.begin(), order.end());
  for (std::size_t t = 0; t < mesh.size(); ++t) ASSERT_EQ(order[t], t) << "every triangle in exactly one leaf";
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0, 1);
  const auto origins = uniformProbes(mesh, rays, 0.1 * mesh.diagonal(), seed);
  std::size_t total = 0;
  for (int i = 0; i < rays; ++i) {
    // Half the rays start at a centroid along the inward normal, as the placement casts them.
    const std::size_t t0 = std::size_t(i) % mesh.size();
    const bool fromCentroid = i % 2 == 0 && !mesh.normals[t0].isZero(0.0);
    const Vec3 origin = fromCentroid ? mesh.centroid(t0) : origins[i];
    Vec3 dir = fromCentroid ? Vec3(-mesh.normals[t0]) : Vec3(g(rng), g(rng), g(rng));
    // A quarter of the others are aimed at a vertex (hits on the corners of boxes, where rounding could
    // lose a box that holds a hit).
    if (!fromCentroid && i % 4 == 1) dir = mesh.vertex(t0, i % 3) - origin;
    const double tMaxInit = i % 3 == 0 ? 0.3 * mesh.diagonal() : std::numeric_limits<double>::infinity();
    std::map<std::uint32_t, double> expected, got;
    for (std::size_t t = 0; t < mesh.size(); ++t) {
      double dist;
      if (rayTriangle(origin, dir, mesh.vertex(t, 0), mesh.vertex(t, 1), mesh.vertex(t, 2), dist) && dist < tMaxInit)
        expected[std::uint32_t(t)] = dist;
    }
    double tMax = tMaxInit;
    bvh.forEachRayHit(origin, dir, tMax, [&](std::uint32_t t, double dist) {
      EXPECT_EQ(got.count(t), 0u) << "triangle reported twice";
      got[t] = dist;
    });
    ASSERT_EQ(got, expected) << "ray " << i;
    total += got.size();
  }
  EXPECT_GT(total, std::size_t(rays) / 10) << "the rays must hit something";
}

TEST(TriangleBvh, EveryHitOfEveryRay) {
  checkRays(*clod_test::loadNormalized(clod_test::sharedMesh("head.off")), 3000, 1);
  checkRays(*clod_test::loadNormalized(clod_test::sharedMesh("mesh_with_border.off")), 2000, 2);
  checkRays(loadMesh(clod_test::testData("cube.obj")), 500, 3);
}

TEST(TriangleBvh, TwoThreadBuildIsTheSameTree) {
  // Above 4096 triangles the root's subtrees are built on two threads: the same nodes, byte for byte,
  // and the same leaf order as the serial build, and every ray still finds every hit.
  const auto mesh = clod_test::loadNormalized(clod_test::sharedMesh("elephant.off"));
  ASSERT_GT(mesh->size(), 4096u);
  const TriangleBvh serial(*mesh, 4, 1), parallel(*mesh, 4, 2);
  ASSERT_EQ(serial.order(), parallel.order());
  ASSERT_EQ(serial.nodes().size(), parallel.nodes().size());
  EXPECT_EQ(std::memcmp(serial.nodes().data(), parallel.nodes().data(),
                        serial.nodes().size() * sizeof(TriangleBvh::Node)),
            0);
  checkRays(*mesh, 1500, 4, 2);
}

TEST(TriangleBvh, OtherLeafSizes) {
  const auto mesh = clod_test::loadNormalized(clod_test::sharedMesh("head.off"));
  for (int leaf : {1, 2, 8}) {
    const TriangleBvh bvh(*mesh, leaf);
    std::size_t rays = 0;
    for (std::size_t t = 0; t < mesh->size(); t += 7) {
      const Vec3 origin = mesh->centroid(t), dir = -mesh->normals[t];
      if (dir.isZero(0.0)) continue;
      std::map<std::uint32_t, double> expected, got;
      for (std::size_t o = 0; o < mesh->size(); ++o) {
        double d;
        if (rayTriangle(origin, dir, mesh->vertex(o, 0), mesh->vertex(o, 1), mesh->vertex(o, 2), d))
          expected[std::uint32_t(o)] = d;
      }
      double tMax = std::numeric_limits<double>::infinity();
      bvh.forEachRayHit(origin, dir, tMax, [&](std::uint32_t o, double d) { got[o] = d; });
      ASSERT_EQ(got, expected) << "leaf size " << leaf << ", triangle " << t;
      ++rays;
    }
    EXPECT_GT(rays, 300u);
  }
}

TEST(TriangleBvh, FlatTrianglesOverAHugeRangeAreAllFound) {
  // Triangles in the planes x = 1.15^i, up to ~1e24 (float bounds of flat boxes far from the origin),
  // one triangle per leaf: a ray along x meets every one of them, built on one thread or two, and
  // random rays find what brute force finds.
  std::vector<Vec3> v;
  std::vector<Triangle> t;
  for (std::uint32_t i = 0; i < 400; ++i) {
    const double x = std::pow(1.15, i);
    v.emplace_back(x, -1, -1);
    v.emplace_back(x, 2, -1);
    v.emplace_back(x, -1, 2);
    t.push_back({3 * i, 3 * i + 1, 3 * i + 2});
  }
  const TriangleMesh mesh = makeMesh(v, t, "chain");
  for (unsigned threads : {1u, 2u}) {
    const TriangleBvh bvh(mesh, 1, threads);
    double tMax = std::numeric_limits<double>::infinity();
    std::size_t hits = 0;
    bvh.forEachRayHit(Vec3(0, 0.1, 0.2), Vec3(1, 0, 0), tMax, [&](std::uint32_t, double) { ++hits; });
    EXPECT_EQ(hits, mesh.size());
  }
  checkRays(mesh, 300, 5);
}

TEST(TriangleBvh, ShrinkingTMaxPrunesFartherHits) {
  const auto mesh = clod_test::loadNormalized(clod_test::sharedMesh("elephant.off"));
  const TriangleBvh bvh(*mesh);
  std::size_t rays = 0;
  for (std::size_t t = 0; t < mesh->size(); t += 13) {
    const Vec3 origin = mesh->centroid(t), dir = -mesh->normals[t];
    double nearest = std::numeric_limits<double>::infinity();
    for (std::size_t o = 0; o < mesh->size(); ++o) {
      double d;
      if (o != t && rayTriangle(origin, dir, mesh->vertex(o, 0), mesh->vertex(o, 1), mesh->vertex(o, 2), d) && d > 1e-9)
        nearest = std::min(nearest, d);
    }
    double tMax = std::numeric_limits<double>::infinity(), found = tMax;
    bvh.forEachRayHit(origin, dir, tMax, [&](std::uint32_t o, double d) {
      if (o == t || d <= 1e-9) return;
      found = std::min(found, d);
      tMax = found;  // first-hit search
    });
    ASSERT_EQ(found, nearest) << "triangle " << t;
    ++rays;
  }
  EXPECT_GT(rays, 100u);
}

// Packets of rays: each ray gets only its own brute-force hits (the same t), and every hit its cull
// asks for: n . m < cap and (n . m < below, or n . m < nearBelow no farther than within), with m, cap,
// below, nearBelow and within drawn per ray (a cull read for the wrong ray would lose some). Half of the
// packets use the cull as a plain distance limit. Coherent packets (neighbouring triangles' inward
// normals, as the placement casts them) and incoherent ones (random rays), of every size up to kPacket.
// A static cull, so what a ray must get is known beforehand.
void checkPackets(const TriangleMesh& mesh, int packets, std::uint64_t seed) {
  const TriangleBvh bvh(mesh, 4, 2);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0, 1);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const double inf = std::numeric_limits<double>::infinity();
  const auto randomOrigins = uniformProbes(mesh, packets * TriangleBvh::kPacket, 0.1 * mesh.diagonal(), seed);
  std::size_t total = 0, pruned = 0, prunedByNormal = 0, tightLimits = 0;
  for (int p = 0; p < packets; ++p) {
    const int count = 1 + p % TriangleBvh::kPacket;
    const bool coherent = p % 3 != 2;
    // Aimed packets: unit rays through a vertex or an edge's midpoint of a triangle, hits on the corners
    // and faces of leaf boxes, where a test in float that is not widened enough loses nodes.
    const bool aimed = p % 5 == 4;
    const bool byNormal = p % 4 >= 2;
    Vec3 origins[TriangleBvh::kPacket], dirs[TriangleBvh::kPacket];
    PacketCull cull;
    const std::size_t start = (std::size_t(p) * 37) % mesh.size();
    for (int r = 0; r < TriangleBvh::kPacket; ++r) {
      const std::uint32_t t = bvh.order()[(start + r) % mesh.size()];
      if (aimed) {
        origins[r] = randomOrigins[std::size_t(p) * TriangleBvh::kPacket + r];
        const Vec3 target = r % 2 ? mesh.vertex(t, r % 3) : Vec3(0.5 * (mesh.vertex(t, r % 3) + mesh.vertex(t, (r + 1) % 3)));
        dirs[r] = (target - origins[r]).normalized();
      } else if (coherent && !mesh.normals[t].isZero(0.0)) {
        origins[r] = mesh.centroid(t);
        dirs[r] = -mesh.normals[t];
      } else {
        origins[r] = randomOrigins[std::size_t(p) * TriangleBvh::kPacket + r];
        dirs[r] = Vec3(g(rng), g(rng), g(rng));
      }
      const Vec3 m = byNormal ? Vec3(-dirs[r].normalized()) : Vec3(g(rng), g(rng), g(rng)).normalized();
      for (int k = 0; k < 3; ++k) cull.axis[k][r] = m[k];
      cull.within[r] = p % 2 ? inf : u(rng) * mesh.diagonal();
      // Tight packets: one brute-force hit of the ray sits exactly on every limit (n . m one step under
      // cap and nearBelow, at the distance within), so a test that rounds a limit the wrong way loses it.
      const bool tight = p % 7 == 3;
      std::vector<std::pair<double, double>> own;  // (t, n . m) of the ray's hits
      if (tight)
        for (std::size_t t2 = 0; t2 < mesh.size(); ++t2) {
          double dist;
          if (rayTriangle(origins[r], dirs[r], mesh.vertex(t2, 0), mesh.vertex(t2, 1), mesh.vertex(t2, 2), dist))
            own.emplace_back(dist, mesh.normals[t2].dot(m));
        }
      if (!own.empty()) {
        const auto& h = own[std::size_t(u(rng) * own.size()) % own.size()];
        cull.cap[r] = std::nextafter(h.second, inf);
        cull.below[r] = h.second - 0.5;
        cull.nearBelow[r] = std::nextafter(h.second, inf);
        cull.within[r] = h.first;
        ++tightLimits;
      } else if (byNormal) {
        cull.cap[r] = -1.0 + 2.0 * u(rng);
        cull.below[r] = -1.0 + 1.5 * u(rng);
        cull.nearBelow[r] = cull.below[r] + 0.5 * u(rng);
      } else {
        cull.cap[r] = inf;
        cull.below[r] = -inf;
        cull.nearBelow[r] = inf;
      }
    }
    std::vector<std::map<std::uint32_t, double>> got(count);
    bvh.forEachPacketHit(origins, dirs, count, cull, [&](int r, std::uint32_t t, double dist) {
      ASSERT_GE(r, 0);
      ASSERT_LT(r, count);
      EXPECT_EQ(got[r].count(t), 0u) << "triangle reported twice";
      got[r][t] = dist;
    });
    for (int r = 0; r < count; ++r) {
      const Vec3 m(cull.axis[0][r], cull.axis[1][r], cull.axis[2][r]);
      for (std::size_t t = 0; t < mesh.size(); ++t) {
        double dist;
        const bool hits = rayTriangle(origins[r], dirs[r], mesh.vertex(t, 0), mesh.vertex(t, 1), mesh.vertex(t, 2), dist);
        const auto it = got[r].find(std::uint32_t(t));
        if (!hits) {
          ASSERT_TRUE(it == got[r].end()) << "packet " << p << " ray " << r << ": triangle " << t << " is no hit";
          continue;
        }
        if (it != got[r].end()) {
          ASSERT_EQ(it->second, dist) << "packet " << p << " ray " << r;
        }
        const double dot = mesh.normals[t].dot(m);
        if (dot < cull.cap[r] && (dot < cull.below[r] || (dot < cull.nearBelow[r] && dist <= cull.within[r]))) {
          ++total;
          ASSERT_TRUE(it != got[r].end()) << "packet " << p << " ray " << r << ": hit on " << t << " at " << dist
                                          << " (n.m " << dot << ") that the cull asks for missed";
        } else if (it == got[r].end()) {
          ++pruned;
          if (byNormal) ++prunedByNormal;
        }
      }
    }
  }
  EXPECT_GT(total, std::size_t(packets)) << "the rays must hit something";
  EXPECT_GT(pruned, 0u) << "the cull must skip something, or the test proves nothing";
  EXPECT_GT(prunedByNormal, 0u) << "the normal bounds must skip something, or the test proves nothing";
  EXPECT_GT(tightLimits, std::size_t(packets)) << "rays with a hit on their limits";
}

TEST(TriangleBvh, PacketsGetEveryHitOfEachRay) {
  // Both kernel sets: AVX2 where the CPU has it, and the baseline (SSE2 on x86-64).
  for (const bool avx2 : {true, false}) {
    detail::usePacketAvx2(avx2);
    SCOPED_TRACE(detail::packetAvx2() ? "AVX2" : "baseline");
    checkPackets(*clod_test::loadNormalized(clod_test::sharedMesh("head.off")), 300, 11);
    checkPackets(*clod_test::loadNormalized(clod_test::sharedMesh("elephant.off")), 200, 12);
    checkPackets(loadMesh(clod_test::testData("cube.obj")), 100, 13);
  }
  detail::usePacketAvx2(true);
}

#if defined(CLOD_PACKET_AVX2)
// The float child test against the double one, on boxes whose faces, edges or corners lie on the rays
// and with every cull limit one step above the double test's value (within: exactly its entry): every
// ray and child the double test keeps, the float test keeps, with an entry no greater. Directions with
// zero and tiny components, scenes from 1e-6 to 1e6.
TEST(TriangleBvh, FloatChildTestKeepsWhatTheDoubleTestKeeps) {
  if (!detail::packetAvx2()) GTEST_SKIP() << "the CPU has no AVX2";
  constexpr int W = TriangleBvh::kPacket;
  std::mt19937_64 rng(23);
  std::normal_distribution<double> g(0, 1);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const double inf = std::numeric_limits<double>::infinity();
  std::size_t kept = 0, tested = 0;
  for (int round = 0; round < 20000; ++round) {
    const double scale = std::pow(10.0, -6 + 12 * u(rng));
    alignas(32) double o[3][W], d[3][W], inv[3][W];
    for (int r = 0; r < W; ++r) {
      Vec3 dir(g(rng), g(rng), g(rng));
      if (r % 4 == 1) dir[r % 3] = 0.0;
      if (r % 4 == 2) dir[(r + 1) % 3] = 1e-12 * dir[(r + 1) % 3];
      dir.normalize();
      for (int k = 0; k < 3; ++k) {
        o[k][r] = scale * g(rng);
        d[k][r] = dir[k];
        const double dk = dir[k] != 0.0 ? dir[k] : std::copysign(1e-300, dir[k]);
        inv[k][r] = 1.0 / dk;
      }
    }
    // Two boxes through a point of one ray: the point on a face, an edge or a corner.
    TriangleBvh::Node nodes[2] = {};
    for (int c = 0; c < 2; ++c) {
      TriangleBvh::Node& node = nodes[c];
      const int r = int(u(rng) * W) % W;
      const double t = scale * 2.0 * u(rng);
      for (int k = 0; k < 3; ++k) {
        const double q = o[k][r] + t * d[k][r];
        const double size = scale * u(rng);
        const int where = int(u(rng) * 3);  // the point at the low face, the high face, or inside
        node.lo[k] = float(where == 0 ? q : where == 1 ? q - size : q - 0.5 * size);
        node.hi[k] = float(where == 0 ? q + size : where == 1 ? q : q + 0.5 * size);
        if (node.lo[k] > node.hi[k]) std::swap(node.lo[k], node.hi[k]);
        const double n1 = 2.0 * u(rng) - 1.0, n2 = 2.0 * u(rng) - 1.0;
        node.normalLo[k] = float(std::min(n1, n2));
        node.normalHi[k] = round % 3 ? float(std::max(n1, n2)) : node.normalLo[k];  // a third single normals
      }
    }
    const unsigned active = (std::uniform_int_distribution<unsigned>(1, (1u << W) - 1))(rng);
    PacketCull cull;
    for (int r = 0; r < W; ++r) {
      const Vec3 m = Vec3(g(rng), g(rng), g(rng)).normalized();
      for (int k = 0; k < 3; ++k) cull.axis[k][r] = m[k];
      cull.cap[r] = cull.below[r] = cull.nearBelow[r] = cull.within[r] = inf;
    }
    const TriangleBvh::Node* const child[2] = {&nodes[0], &nodes[1]};
    alignas(32) double entryD[2][W], entryF[2][W];
    double* const ed[2] = {entryD[0], entryD[1]};
    double* const ef[2] = {entryF[0], entryF[1]};
    unsigned maskD[2], maskF[2];
    // First the entries, then every limit set one step above the values of one child, chosen per ray.
    detail::packetChildrenAvx2(child, &o[0][0], &inv[0][0], cull, active, ed, maskD);
    for (int r = 0; r < W; ++r) {
      const int c = r % 2;
      const Vec3 m(cull.axis[0][r], cull.axis[1][r], cull.axis[2][r]);
      const double lower = TriangleBvh::minDot(nodes[c], m) - PacketCull::kSlack;
      cull.cap[r] = std::nextafter(lower, inf);
      const int rule = round % 3;  // kept through below, or through nearBelow and within
      cull.below[r] = rule == 0 ? std::nextafter(lower, inf) : lower;
      cull.nearBelow[r] = std::nextafter(lower, inf);
      cull.within[r] = ((maskD[c] >> r) & 1u) ? entryD[c][r] : inf;
    }
    detail::packetChildrenAvx2(child, &o[0][0], &inv[0][0], cull, active, ed, maskD);
    detail::PacketFloat f;
    double sceneBound = 0.0;
    for (int c = 0; c < 2; ++c)
      for (int k = 0; k < 3; ++k)
        sceneBound = std::max({sceneBound, std::fabs(double(nodes[c].lo[k])), std::fabs(double(nodes[c].hi[k]))});
    ASSERT_TRUE(f.set(&o[0][0], &d[0][0], &inv[0][0], W, sceneBound, cull)) << "round " << round;
    detail::packetChildrenAvx2f(child, f, active, ef, maskF);
    for (int c = 0; c < 2; ++c) {
      ASSERT_EQ(maskD[c] & ~maskF[c], 0u) << "round " << round << " child " << c << ": a node kept in double is lost";
      ASSERT_EQ(maskF[c] & ~active, 0u);
      for (int r = 0; r < W; ++r)
        if ((maskD[c] >> r) & 1u) {
          ++kept;
          ASSERT_LE(entryF[c][r], entryD[c][r]) << "round " << round << " child " << c << " ray " << r;
        }
      tested += __builtin_popcount(active);
    }
  }
  EXPECT_GT(kept, tested / 50) << "the double test must keep rays, or the test proves nothing";
}

// The AVX2 triangle test against rayTriangle, bit for bit, on the cases where a different order of
// operations or a missed NaN would show: rays through vertices and edges of triangles on an integer grid
// (u, v, u + v exactly 0 or 1), degenerate triangles, directions with zero components, coordinates that
// overflow the determinant (inf, NaN) or underflow it, and every subset of active rays.
TEST(TriangleBvh, PacketTriangleTestIsRayTriangleBitForBit) {
  if (!detail::packetAvx2()) GTEST_SKIP() << "the CPU has no AVX2";
  constexpr int W = TriangleBvh::kPacket;
  std::mt19937_64 rng(21);
  std::uniform_int_distribution<int> cell(-3, 3), pick(0, 7), lane(0, (1 << W) - 1);
  std::normal_distribution<double> g(0, 1);
  const double scales[] = {1.0, 1e-3, 1e-160, 1e160, 1e300};
  std::size_t hits = 0, misses = 0, compared = 0;
  for (int round = 0; round < 20000; ++round) {
    const double scale = scales[round % 5];
    Vec3 v[3];
    for (Vec3& x : v) x = Vec3(cell(rng), cell(rng), cell(rng)) * scale;
    if (round % 7 == 0) v[2] = v[0] + 2.0 * (v[1] - v[0]);  // collinear
    if (round % 11 == 0) v[1] = v[0];                      // two equal vertices
    alignas(32) double o[3][W], d[3][W];
    for (int r = 0; r < W; ++r) {
      // Aimed at a vertex, an edge's midpoint, the centroid or a grid point, from a grid offset, or random.
      Vec3 target;
      switch (pick(rng)) {
        case 0: target = v[r % 3]; break;
        case 1: target = 0.5 * (v[r % 3] + v[(r + 1) % 3]); break;
        case 2: target = (v[0] + v[1] + v[2]) / 3.0; break;
        case 3: target = Vec3(cell(rng), cell(rng), cell(rng)) * scale; break;
        default: target = v[0] + g(rng) * (v[1] - v[0]) + g(rng) * (v[2] - v[0]); break;
      }
      Vec3 from = target + Vec3(cell(rng), cell(rng), cell(rng)) * scale;
      if (r % 5 == 0) from = target + Vec3(0, 0, 2) * scale;  // axis-aligned: two zero components
      if (r % 7 == 3) from = target + Vec3(g(rng), g(rng), g(rng)) * 1e300;  // u, v overflow to inf or NaN
      Vec3 dir = r % 9 == 8 ? Vec3(g(rng), g(rng), g(rng)) : Vec3(target - from);
      for (int k = 0; k < 3; ++k) {
        o[k][r] = from[k];
        d[k][r] = dir[k];
      }
    }
    const unsigned active = round % 3 ? lane(rng) : (1u << W) - 1;
    alignas(32) double t[W];
    const unsigned got = detail::packetTriangleAvx2(v[0].data(), v[1].data(), v[2].data(), &o[0][0], &d[0][0], active, t);
    ASSERT_EQ(got & ~active, 0u) << "only active rays hit";
    for (int r = 0; r < W; ++r) {
      if (!((active >> r) & 1u)) continue;
      double expect = 0.0;
      const bool hit = rayTriangle(Vec3(o[0][r], o[1][r], o[2][r]), Vec3(d[0][r], d[1][r], d[2][r]), v[0], v[1], v[2], expect);
      ++compared;
      ASSERT_EQ(hit, bool((got >> r) & 1u)) << "round " << round << " ray " << r;
      if (hit) {
        ++hits;
        std::uint64_t a, b;
        std::memcpy(&a, &expect, 8);
        std::memcpy(&b, &t[r], 8);
        ASSERT_EQ(a, b) << "round " << round << " ray " << r << ": t " << expect << " vs " << t[r];
      } else {
        ++misses;
      }
    }
  }
  EXPECT_GT(hits, compared / 10) << "the cases must hit often, or the distances are barely compared";
  EXPECT_GT(misses, compared / 10);
}

#endif  // CLOD_PACKET_AVX2

}  // namespace
