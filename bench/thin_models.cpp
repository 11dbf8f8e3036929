#include "thin_models.h"

#include <cmath>
#include <cstdint>

namespace clod_bench {
namespace {

using clod_haptics::Triangle;
using clod_haptics::TriangleMesh;
using clod_haptics::Vec3;

/** Closed parts appended into one vertex and triangle list. */
struct Builder {
  std::vector<Vec3> v;
  std::vector<Triangle> t;

  std::uint32_t add(const Vec3& p) {
    v.push_back(p);
    return static_cast<std::uint32_t>(v.size() - 1);
  }
  void tri(std::uint32_t a, std::uint32_t b, std::uint32_t c) { t.push_back(Triangle{{a, b, c}}); }

  // A grid of (nu + 1) x (nv + 1) points origin + u * du + v * dv, split at the given fractions; returns indices.
  std::vector<std::uint32_t> grid(const Vec3& origin, const Vec3& du, const Vec3& dv, const std::vector<double>& us,
                                  const std::vector<double>& vs) {
    std::vector<std::uint32_t> ids;
    for (double b : vs)
      for (double a : us) ids.push_back(add(origin + a * du + b * dv));
    return ids;
  }
  void quads(const std::vector<std::uint32_t>& ids, std::size_t nu, std::size_t nv, bool flip) {
    for (std::size_t j = 0; j + 1 < nv; ++j)
      for (std::size_t i = 0; i + 1 < nu; ++i) {
        const std::uint32_t a = ids[j * nu + i], b = ids[j * nu + i + 1], c = ids[(j + 1) * nu + i + 1],
                            d = ids[(j + 1) * nu + i];
        if (flip) {
          tri(a, c, b);
          tri(a, d, c);
        } else {
          tri(a, b, c);
          tri(a, c, d);
        }
      }
  }

  // A closed box centred at c with half sizes h (x, y: the plate, z: its thickness), the large faces split at
  // us x vs (fractions of the side, from 0 to 1), the rims in one strip of long triangles. Shared vertices on the
  // edges: the large faces' boundary points are reused by the rims.
  void plate(const Vec3& c, const Vec3& h, const std::vector<double>& us, const std::vector<double>& vs) {
    const std::size_t nu = us.size(), nv = vs.size();
    const Vec3 o0 = c + Vec3(-h.x(), -h.y(), -h.z()), o1 = c + Vec3(-h.x(), -h.y(), h.z());
    const Vec3 du(2 * h.x(), 0, 0), dv(0, 2 * h.y(), 0);
    const auto bottom = grid(o0, du, dv, us, vs), top = grid(o1, du, dv, us, vs);
    quads(bottom, nu, nv, true);
    quads(top, nu, nv, false);
    // The boundary loop of each face, counter-clockwise seen from +z.
    std::vector<std::uint32_t> lb, lt;
    for (std::size_t i = 0; i < nu; ++i) lb.push_back(bottom[i]), lt.push_back(top[i]);
    for (std::size_t j = 1; j < nv; ++j) lb.push_back(bottom[j * nu + nu - 1]), lt.push_back(top[j * nu + nu - 1]);
    for (std::size_t i = nu - 1; i-- > 0;) lb.push_back(bottom[(nv - 1) * nu + i]), lt.push_back(top[(nv - 1) * nu + i]);
    for (std::size_t j = nv - 1; j-- > 1;) lb.push_back(bottom[j * nu]), lt.push_back(top[j * nu]);
    for (std::size_t k = 0; k < lb.size(); ++k) {
      const std::size_t n = (k + 1) % lb.size();
      tri(lb[k], lb[n], lt[n]);
      tri(lb[k], lt[n], lt[k]);
    }
  }

  // A closed cylinder from a to b of radius r, `segments` around and `rings` + 1 circles along (rings = 1: long
  // triangles from end to end), capped by fans.
  void cylinder(const Vec3& a, const Vec3& b, double r, int segments, int rings) {
    const Vec3 axis = (b - a).normalized();
    const Vec3 helper = std::abs(axis.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY();
    const Vec3 e1 = axis.cross(helper).normalized(), e2 = axis.cross(e1);
    const std::uint32_t first = static_cast<std::uint32_t>(v.size());
    for (int k = 0; k <= rings; ++k) {
      const Vec3 centre = a + (b - a) * (static_cast<double>(k) / rings);
      for (int s = 0; s < segments; ++s) {
        const double phi = 2 * M_PI * s / segments;
        add(centre + r * (std::cos(phi) * e1 + std::sin(phi) * e2));
      }
    }
    auto at = [&](int k, int s) { return first + static_cast<std::uint32_t>(k * segments + (s % segments)); };
    for (int k = 0; k < rings; ++k)
      for (int s = 0; s < segments; ++s) {
        tri(at(k, s), at(k + 1, s + 1), at(k + 1, s));
        tri(at(k, s), at(k, s + 1), at(k + 1, s + 1));
      }
    const std::uint32_t ca = add(a), cb = add(b);
    for (int s = 0; s < segments; ++s) {
      tri(ca, at(0, s), at(0, s + 1));
      tri(cb, at(rings, s + 1), at(rings, s));
    }
  }

  // A closed UV sphere (ellipsoid with half axes h).
  void ellipsoid(const Vec3& c, const Vec3& h, int slices, int stacks) {
    const std::uint32_t south = add(c - Vec3(0, 0, h.z())), first = static_cast<std::uint32_t>(v.size());
    for (int k = 1; k < stacks; ++k) {
      const double theta = M_PI * k / stacks - M_PI / 2;
      for (int s = 0; s < slices; ++s) {
        const double phi = 2 * M_PI * s / slices;
        add(c + Vec3(h.x() * std::cos(theta) * std::cos(phi), h.y() * std::cos(theta) * std::sin(phi),
                     h.z() * std::sin(theta)));
      }
    }
    const std::uint32_t north = add(c + Vec3(0, 0, h.z()));
    auto at = [&](int k, int s) { return first + static_cast<std::uint32_t>((k - 1) * slices + (s % slices)); };
    for (int s = 0; s < slices; ++s) {
      tri(south, at(1, s + 1), at(1, s));
      tri(north, at(stacks - 1, s), at(stacks - 1, s + 1));
    }
    for (int k = 1; k + 1 < stacks; ++k)
      for (int s = 0; s < slices; ++s) {
        tri(at(k, s), at(k, s + 1), at(k + 1, s + 1));
        tri(at(k, s), at(k + 1, s + 1), at(k + 1, s));
      }
  }

  // A closed curved shell of thickness th about the surface f(u, w), u and w in [0, 1] on an nu x nw grid: the two
  // offset sheets (f +- th / 2 along the surface normal), closed at w = 0 and w = 1 by strips, and at u = 0 and
  // u = 1 too unless the surface wraps around in u (f(0, w) = f(1, w)). Outward wound when f_u x f_w points to
  // the first sheet's side.
  template <class F>
  void shell(F f, int nu, int nw, double th, bool wrapU) {
    auto normal = [&](double u, double w) {
      const double e = 1e-6;
      return Vec3((f(u + e, w) - f(u - e, w)).cross(f(u, w + e) - f(u, w - e)).normalized());
    };
    const int cu = wrapU ? nu : nu + 1;
    const std::uint32_t first = static_cast<std::uint32_t>(v.size());
    for (int side = 0; side < 2; ++side)
      for (int j = 0; j <= nw; ++j)
        for (int i = 0; i < cu; ++i) {
          const double u = static_cast<double>(i) / nu, w = static_cast<double>(j) / nw;
          add(f(u, w) + (side == 0 ? 0.5 : -0.5) * th * normal(u, w));
        }
    auto at = [&](int side, int i, int j) {
      return first + static_cast<std::uint32_t>(side * cu * (nw + 1) + j * cu + (wrapU ? i % nu : i));
    };
    auto quad = [&](std::uint32_t a, std::uint32_t b, std::uint32_t c, std::uint32_t d) {
      tri(a, b, c);
      tri(a, c, d);
    };
    for (int j = 0; j < nw; ++j)
      for (int i = 0; i < nu; ++i) {
        quad(at(0, i, j), at(0, i + 1, j), at(0, i + 1, j + 1), at(0, i, j + 1));
        quad(at(1, i, j), at(1, i, j + 1), at(1, i + 1, j + 1), at(1, i + 1, j));
      }
    for (int i = 0; i < nu; ++i) {
      quad(at(0, i, 0), at(1, i, 0), at(1, i + 1, 0), at(0, i + 1, 0));
      quad(at(0, i + 1, nw), at(1, i + 1, nw), at(1, i, nw), at(0, i, nw));
    }
    if (!wrapU)
      for (int j = 0; j < nw; ++j) {
        quad(at(0, 0, j + 1), at(1, 0, j + 1), at(1, 0, j), at(0, 0, j));
        quad(at(0, nu, j), at(1, nu, j), at(1, nu, j + 1), at(0, nu, j + 1));
      }
  }

  TriangleMesh mesh(const std::string& name) { return clod_haptics::makeMesh(v, t, name); }
};

std::vector<double> uniform(int n) {
  std::vector<double> f;
  for (int i = 0; i <= n; ++i) f.push_back(static_cast<double>(i) / n);
  return f;
}

// Fine steps on [0, 0.5], then one long step to 1: small triangles beside long ones.
std::vector<double> mixed(int n) {
  std::vector<double> f;
  for (int i = 0; i <= n; ++i) f.push_back(0.5 * i / n);
  f.push_back(1.0);
  return f;
}

}  // namespace

std::vector<ThinModel> thinModels() {
  std::vector<ThinModel> models;
  {
    Builder b;
    b.plate(Vec3::Zero(), Vec3(0.4, 0.25, 0.0025), uniform(40), uniform(25));
    models.push_back({"plate-0.005", "plate 0.8 x 0.5 x 0.005, faces 40 x 25", b.mesh("plate-0.005")});
  }
  {
    Builder b;
    b.plate(Vec3::Zero(), Vec3(0.4, 0.25, 0.015), {0.0, 1.0}, {0.0, 1.0});
    models.push_back({"plate-0.03-long", "plate 0.8 x 0.5 x 0.03, each face two triangles", b.mesh("plate-0.03-long")});
  }
  {
    Builder b;
    b.plate(Vec3::Zero(), Vec3(0.4, 0.25, 0.0075), mixed(20), mixed(12));
    models.push_back({"plate-0.015-mixed", "plate 0.8 x 0.5 x 0.015, a quarter fine, the rest long triangles",
                      b.mesh("plate-0.015-mixed")});
  }
  {
    Builder b;
    b.cylinder(Vec3(-0.4, 0, 0), Vec3(0.4, 0, 0), 0.01, 12, 1);
    models.push_back({"cylinder-0.02-long", "cylinder 0.8 long, 0.02 thick, 12 long triangles end to end",
                      b.mesh("cylinder-0.02-long")});
  }
  {
    Builder b;
    b.cylinder(Vec3(-0.4, 0, 0), Vec3(0.4, 0, 0), 0.025, 16, 40);
    models.push_back({"cylinder-0.05", "cylinder 0.8 long, 0.05 thick, 16 x 40", b.mesh("cylinder-0.05")});
  }
  {
    // Antlers: a trunk, branches, and thin plates ("ears") off them.
    Builder b;
    b.cylinder(Vec3(0, 0, -0.4), Vec3(0, 0, 0.2), 0.03, 16, 24);
    for (int k = 0; k < 4; ++k) {
      const double phi = M_PI / 2 * k + 0.3, z = -0.2 + 0.12 * k;
      const Vec3 base(0, 0, z), tip = base + Vec3(0.35 * std::cos(phi), 0.35 * std::sin(phi), 0.2);
      b.cylinder(base, tip, 0.012, 10, k % 2 ? 1 : 12);
      const Vec3 twig = tip + Vec3(0.1 * std::cos(phi + 1), 0.1 * std::sin(phi + 1), 0.12);
      b.cylinder(tip - 0.05 * (tip - base).normalized(), twig, 0.007, 8, 4);
    }
    b.plate(Vec3(0.0, 0.0, 0.32), Vec3(0.2, 0.12, 0.005), uniform(16), uniform(10));
    b.plate(Vec3(0.0, 0.0, 0.24), Vec3(0.12, 0.2, 0.01), {0.0, 1.0}, {0.0, 1.0});
    models.push_back({"branches", "trunk 0.06, branches 0.024 and twigs 0.014 thick, plates 0.01 and 0.02",
                      b.mesh("branches")});
  }
  {
    // A body on four thin legs.
    Builder b;
    b.ellipsoid(Vec3(0, 0, 0.25), Vec3(0.35, 0.18, 0.15), 48, 24);
    for (int k = 0; k < 4; ++k) {
      const double x = k < 2 ? -0.22 : 0.22, y = k % 2 ? -0.09 : 0.09;
      b.cylinder(Vec3(x, y, 0.2), Vec3(x * 1.1, y * 1.3, -0.4), 0.02, 16, 30);
    }
    models.push_back({"legs", "ellipsoid body 0.7 x 0.36 x 0.3 on four legs 0.04 thick", b.mesh("legs")});
  }
  {
    // Held out (added 2026-11-29, after the box's middle was chosen on cylinder-0.02-long): a body on six thinner legs
    // leaning out, three of them long triangles end to end, three in fine rings.
    Builder b;
    b.ellipsoid(Vec3(0, 0, 0.25), Vec3(0.25, 0.12, 0.1), 64, 32);
    for (int k = 0; k < 6; ++k) {
      const double x = -0.16 + 0.16 * (k / 2), y = k % 2 ? -0.06 : 0.06;
      b.cylinder(Vec3(x, y, 0.2), Vec3(x * 1.6, y * 4.0, -0.35), 0.01, 12, k % 2 ? 1 : 40);
    }
    models.push_back({"insect", "ellipsoid body 0.5 x 0.24 x 0.2 on six legs 0.02 thick, three of long triangles",
                      b.mesh("insect")});
  }
  // Curved thin shells (added 2026-11-28, after the thin-patch settling was tuned on the flat plates: held out).
  {
    Builder b;
    b.shell([](double u,
               double w) { return Vec3(0.2 * std::cos(2 * M_PI * u), 0.2 * std::sin(2 * M_PI * u), 0.4 * w - 0.2); },
            48, 20, 0.004, true);
    models.push_back({"tube-shell-0.004", "open tube of radius 0.2, 0.4 long, wall 0.004", b.mesh("tube-shell-0.004")});
  }
  {
    Builder b;
    b.shell([](double u, double w) { return Vec3(0.7 * u - 0.35, 0.4 * w - 0.2, 0.06 * std::sin(2 * M_PI * u / 0.5)); },
            35, 20, 0.006, false);
    models.push_back({"wavy-plate-0.006", "plate 0.7 x 0.4 waved by 0.06, 0.006 thick", b.mesh("wavy-plate-0.006")});
  }
  {
    Builder b;
    b.shell(
        [](double u, double w) {
          const double theta = 0.1 + 0.9 * w, phi = 2 * M_PI * u;  // clear of the pole, where the sheets would meet
          return Vec3(0.3 * std::sin(theta) * std::cos(phi), 0.3 * std::sin(theta) * std::sin(phi),
                      0.3 * std::cos(theta));
        },
        40, 15, 0.01, true);
    models.push_back(
        {"cap-shell-0.01", "spherical zone of radius 0.3 from 6 to 57 degrees, 0.01 thick", b.mesh("cap-shell-0.01")});
  }
  return models;
}

}  // namespace clod_bench
