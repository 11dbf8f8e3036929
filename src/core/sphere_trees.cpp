#include "clod_haptics/core/sphere_trees.h"

#include <algorithm>

#include "float_rounding.h"
#include "vector_bytes.h"

namespace clod_haptics {
namespace {

/** The boxes of the spheres' balls. */
std::vector<Eigen::AlignedBox3d> ballBoxes(const ClodSphereSet& s) {
  std::vector<Eigen::AlignedBox3d> boxes(s.size());
  for (std::size_t i = 0; i < s.size(); ++i)
    boxes[i] =
        Eigen::AlignedBox3d(s.centres[i] - Vec3::Constant(s.radii[i]), s.centres[i] + Vec3::Constant(s.radii[i]));
  return boxes;
}

/** Per sphere, the box of the triangles it lists intersected with its ball's box. */
std::vector<Eigen::AlignedBox3d> tightBoxes(const TriangleMesh& m, const ClodSphereSet& s,
                                            const std::vector<Eigen::AlignedBox3d>& balls) {
  std::vector<Eigen::AlignedBox3d> tight(s.size());
  for (std::size_t i = 0; i < s.size(); ++i) {
    tight[i].setEmpty();
    for (const std::uint32_t* t = s.begin(i); t != s.end(i); ++t)
      for (int v = 0; v < 3; ++v) tight[i].extend(m.vertex(*t, v));
    tight[i] = tight[i].intersection(balls[i]);
  }
  return tight;
}

/** The centres as empty boxes. */
std::vector<Eigen::AlignedBox3d> centreBoxes(const ClodSphereSet& s) {
  std::vector<Eigen::AlignedBox3d> points(s.size());
  for (std::size_t i = 0; i < s.size(); ++i) points[i] = Eigen::AlignedBox3d(s.centres[i], s.centres[i]);
  return points;
}

/** Per gap node, the largest padded radius below it rounded up to float. Children follow their parent (left at
 * +1, right at first): filled from the back. */
std::vector<float> gapRadii(const std::vector<BoxNode>& nodes, const std::vector<std::uint32_t>& order,
                            const ClodSphereSet& s, double pad) {
  std::vector<float> maxRadius(nodes.size(), 0.0f);
  for (std::size_t n = nodes.size(); n-- > 0;) {
    const BoxNode& node = nodes[n];
    float m = 0.0f;
    if (node.count > 0) {
      for (std::uint32_t j = node.first; j < node.first + node.count; ++j)
        m = std::max(m, detail::roundUp(s.radii[order[j]] + pad));
    } else {
      m = std::max(maxRadius[n + 1], maxRadius[node.first]);
    }
    maxRadius[n] = m;
  }
  return maxRadius;
}

}  // namespace

std::size_t SphereTrees::bytes() const {
  using detail::bytesOf;
  return bytesOf(ballNodes) + bytesOf(ballOrder) + bytesOf(tightNodes) + bytesOf(tightOrder) + bytesOf(gapNodes) +
         bytesOf(gapOrder) + bytesOf(gapRadius);
}

SphereTrees buildSphereTrees(const TriangleMesh& mesh, const ClodSphereSet& set, double pad) {
  SphereTrees t;
  const std::vector<Eigen::AlignedBox3d> balls = ballBoxes(set);
  buildBoxTree(balls, 4, pad, t.ballNodes, t.ballOrder);
  buildBoxTree(tightBoxes(mesh, set, balls), 1, pad, t.tightNodes, t.tightOrder);
  buildBoxTree(centreBoxes(set), 4, pad, t.gapNodes, t.gapOrder);
  t.gapRadius = gapRadii(t.gapNodes, t.gapOrder, set, pad);
  return t;
}

std::string sphereTreesProblem(const SphereTrees& trees, const TriangleMesh& mesh, const ClodSphereSet& set,
                               double pad) {
  const std::size_t n = set.size();
  const std::vector<Eigen::AlignedBox3d> balls = ballBoxes(set);
  std::string problem = boxTreeProblem(
      trees.ballNodes, trees.ballOrder, n,
      [&](const BoxNode& node, std::uint32_t i) { return nodeHoldsPadded(node, balls[i], pad); }, "sphere");
  if (!problem.empty()) return "ball tree: " + problem;
  const std::vector<Eigen::AlignedBox3d> tight = tightBoxes(mesh, set, balls);
  problem = boxTreeProblem(
      trees.tightNodes, trees.tightOrder, n,
      [&](const BoxNode& node, std::uint32_t i) { return tight[i].isEmpty() || nodeHoldsPadded(node, tight[i], pad); },
      "sphere");
  if (!problem.empty()) return "tight tree: " + problem;
  problem = boxTreeProblem(
      trees.gapNodes, trees.gapOrder, n,
      [&](const BoxNode& node, std::uint32_t i) {
        return nodeHoldsPadded(node, Eigen::AlignedBox3d(set.centres[i], set.centres[i]), pad);
      },
      "sphere");
  if (!problem.empty()) return "gap tree: " + problem;
  if (trees.gapRadius.size() != trees.gapNodes.size()) return "gap tree: one radius per node expected";
  const std::vector<float> needed = gapRadii(trees.gapNodes, trees.gapOrder, set, pad);
  for (std::size_t i = 0; i < needed.size(); ++i)
    if (!(trees.gapRadius[i] >= needed[i])) return "gap tree: a node's radius is below a sphere's";
  return "";
}

}  // namespace clod_haptics
