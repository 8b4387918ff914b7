// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/stages/internal/SpatialOrder.h>

#include <algorithm>
#include <cmath>
#include <utility>

namespace femesher {
namespace internal {

namespace {
uint64_t spread(uint64_t x) {  // 21 bits -> every third bit
  x &= 0x1FFFFF;
  x = (x | x << 32) & 0x1F00000000FFFFull;
  x = (x | x << 16) & 0x1F0000FF0000FFull;
  x = (x | x << 8) & 0x100F00F00F00F00Full;
  x = (x | x << 4) & 0x10C30C30C30C30C3ull;
  x = (x | x << 2) & 0x1249249249249249ull;
  return x;
}

/// Morton codes of `points` on a grid of `cell` from their lower corner, paired with the index.
std::vector<std::pair<uint64_t, uint32_t>> keyed(const std::vector<Vec3>& points, double cell) {
  Vec3 lo{1e300, 1e300, 1e300};
  for (const auto& p : points)
    for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], p[a]);
  std::vector<std::pair<uint64_t, uint32_t>> k(points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    uint64_t code = 0;
    for (int a = 0; a < 3; ++a)
      code |= spread(uint64_t(std::max(0.0, (points[i][a] - lo[a]) / cell))) << a;
    k[i] = {code, uint32_t(i)};
  }
  std::sort(k.begin(), k.end());
  return k;
}

/// A cell that spreads the points' box over the 2^21 steps per axis.
double fittingCell(const std::vector<Vec3>& points) {
  double lo = 1e300, hi = -1e300;
  for (const auto& p : points)
    for (int a = 0; a < 3; ++a) lo = std::min(lo, p[a]), hi = std::max(hi, p[a]);
  return points.empty() || !(hi > lo) ? 1.0 : (hi - lo) / double((1 << 21) - 1);
}
}  // namespace

std::vector<uint32_t> mortonOrder(const std::vector<Vec3>& points, double cell) {
  const auto k = keyed(points, cell);
  std::vector<uint32_t> order(k.size());
  for (size_t i = 0; i < k.size(); ++i) order[i] = k[i].second;
  return order;
}

void spatiallyRenumber(std::vector<Vec3>& points, std::vector<std::array<int32_t, 4>>& tets,
                       std::vector<int32_t>& labels) {
  const double cell = fittingCell(points);
  const std::vector<uint32_t> order = mortonOrder(points, cell);
  std::vector<int32_t> newIndex(points.size());
  std::vector<Vec3> sorted(points.size());
  for (size_t i = 0; i < order.size(); ++i) {
    newIndex[order[i]] = int32_t(i);
    sorted[i] = points[order[i]];
  }
  points = std::move(sorted);
  std::vector<Vec3> centroids(tets.size());
  for (size_t t = 0; t < tets.size(); ++t) {
    auto& T = tets[t];
    Vec3 c{0, 0, 0};
    for (auto& v : T) {
      v = newIndex[size_t(v)];
      for (int a = 0; a < 3; ++a) c[a] += 0.25 * points[size_t(v)][a];
    }
    centroids[t] = c;
  }
  const std::vector<uint32_t> tetOrder = mortonOrder(centroids, cell);
  std::vector<std::array<int32_t, 4>> newTets(tets.size());
  std::vector<int32_t> newLabels(labels.size());
  for (size_t i = 0; i < tetOrder.size(); ++i) {
    newTets[i] = tets[tetOrder[i]];
    newLabels[i] = labels[tetOrder[i]];
  }
  tets = std::move(newTets);
  labels = std::move(newLabels);
}

}  // namespace internal
}  // namespace femesher
