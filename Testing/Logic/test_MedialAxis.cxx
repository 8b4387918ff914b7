// SPDX-License-Identifier: GPL-3.0-or-later
// Integer Medial Axis on generated shapes with known axes, pruning monotonicity, invariances and
// degenerate inputs.
#include <femesher/Status.h>
#include <femesher/Types.h>
#include <femesher/stages/MedialAxis.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <set>

#include "MeshInvariants.h"

using namespace femesher;
using namespace femesher::testing;

namespace {

Grid3 grid(int nx, int ny, int nz, double s = 1) {
  Grid3 g;
  g.dims = {{nx, ny, nz}};
  g.spacing = {{s, s, s}};
  return g;
}

/// Region from a predicate on voxel indices.
std::vector<uint8_t> shape(const Grid3& g, const std::function<bool(int, int, int)>& in) {
  std::vector<uint8_t> m(g.size(), 0);
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i) m[g.index(i, j, k)] = in(i, j, k) ? 1 : 0;
  return m;
}

MedialAxisParameters prune(MedialAxisPruning p, double gamma) {
  MedialAxisParameters mp;
  mp.pruning = p;
  mp.gamma = gamma;
  mp.threads = 2;
  return mp;
}

/// Every medial voxel lies in the region and its radius equals the brute-force distance to the
/// nearest non-region voxel (outside the volume counts as non-region).
void expectInsideWithExactRadius(const Grid3& g, const std::vector<uint8_t>& region,
                                 const MedialAxis& axis) {
  ASSERT_EQ(axis.voxels.size(), axis.radius.size());
  EXPECT_TRUE(std::is_sorted(axis.voxels.begin(), axis.voxels.end()));
  for (size_t n = 0; n < axis.voxels.size(); ++n) {
    const uint32_t v = axis.voxels[n];
    ASSERT_LT(v, g.size());
    ASSERT_TRUE(region[v]) << "medial voxel outside its material";
    const auto c = g.coords(v);
    double best = std::numeric_limits<double>::infinity();
    for (int k = -1; k <= g.dims[2]; ++k)
      for (int j = -1; j <= g.dims[1]; ++j)
        for (int i = -1; i <= g.dims[0]; ++i) {
          if (g.inside(i, j, k) && region[g.index(i, j, k)]) continue;
          best = std::min(best, g.squaredDistance(i - c[0], j - c[1], k - c[2]));
        }
    ASSERT_NEAR(axis.radius[n], std::sqrt(best), 1e-5);
  }
}

std::set<uint32_t> asSet(const MedialAxis& a) { return {a.voxels.begin(), a.voxels.end()}; }

}  // namespace

TEST(MedialAxis, BallShrinksToCentreUnderPruning) {
  const Grid3 g = grid(33, 33, 33);
  const double R = 13;
  const auto ball = shape(g, [&](int i, int j, int k) {
    return (i - 16) * (i - 16) + (j - 16) * (j - 16) + (k - 16) * (k - 16) <= R * R;
  });
  const MedialAxis exact = computeMedialAxis(g, ball, prune(MedialAxisPruning::None, 1));
  const MedialAxis pruned = computeMedialAxis(g, ball, MedialAxisParameters{});
  ASSERT_FALSE(pruned.voxels.empty());
  EXPECT_LE(pruned.voxels.size(), 7u);  // the centre voxel (1 here)
  EXPECT_GT(exact.voxels.size(), 1000u);
  for (uint32_t v : pruned.voxels) {
    const auto c = g.coords(v);
    const double r = std::sqrt(double(g.squaredDistance(c[0] - 16, c[1] - 16, c[2] - 16)));
    EXPECT_LE(r, 0.2 * R) << "pruned ball axis far from the centre";
  }
  expectInsideWithExactRadius(g, ball, pruned);
  // The exact IMA reaches near the boundary (spurious branches): that is why we prune.
  double maxR = 0;
  for (uint32_t v : exact.voxels) {
    const auto c = g.coords(v);
    maxR = std::max(maxR, std::sqrt(g.squaredDistance(c[0] - 16, c[1] - 16, c[2] - 16)));
  }
  EXPECT_GT(maxR, 0.5 * R);
}

TEST(MedialAxis, BoxKeepsItsMidPlane) {
  // Box 1..29 x 1..19 x 1..11 (odd sizes): mid-plane z = 6 at radius 6.
  const Grid3 g = grid(31, 21, 13);
  const auto box = shape(g, [](int i, int j, int k) {
    return i >= 1 && i <= 29 && j >= 1 && j <= 19 && k >= 1 && k <= 11;
  });
  const MedialAxis axis = computeMedialAxis(g, box, MedialAxisParameters{});
  const auto set = asSet(axis);
  for (int i = 10; i <= 20; ++i)
    for (int j = 8; j <= 12; ++j) EXPECT_TRUE(set.count(uint32_t(g.index(i, j, 6)))) << i << "," << j;
  // The sheet is thin: no medial voxel off the mid-plane in the central part.
  for (uint32_t v : axis.voxels) {
    const auto c = g.coords(v);
    if (c[0] >= 10 && c[0] <= 20 && c[1] >= 8 && c[1] <= 12) EXPECT_EQ(c[2], 6);
  }
  const size_t centre = std::find(axis.voxels.begin(), axis.voxels.end(),
                                  uint32_t(g.index(15, 10, 6))) - axis.voxels.begin();
  ASSERT_LT(centre, axis.voxels.size());
  EXPECT_FLOAT_EQ(axis.radius[centre], 6.0f);
  expectInsideWithExactRadius(g, box, axis);
}

TEST(MedialAxis, CylinderAxisNearCentreLine) {
  const Grid3 g = grid(44, 21, 21);
  const auto cyl = shape(g, [](int i, int j, int k) {
    return i >= 2 && i <= 41 && (j - 10) * (j - 10) + (k - 10) * (k - 10) <= 64;
  });
  const MedialAxis axis = computeMedialAxis(g, cyl, MedialAxisParameters{});
  const auto set = asSet(axis);
  int onLine = 0;
  for (int i = 12; i <= 31; ++i) onLine += set.count(uint32_t(g.index(i, 10, 10))) ? 1 : 0;
  EXPECT_GE(onLine, 18);  // the centre line is (almost) all medial
  for (uint32_t v : axis.voxels) {
    const auto c = g.coords(v);
    if (c[0] < 12 || c[0] > 31) continue;  // caps: the axis fans out towards the rims
    EXPECT_LE(std::hypot(c[1] - 10, c[2] - 10), 2.0) << "off-axis voxel " << c[0];
  }
}

TEST(MedialAxis, TorusAxisNearCoreCircle) {
  const Grid3 g = grid(41, 41, 15);
  const double Rc = 13, r = 5;
  auto distToCore = [&](double x, double y, double z) {
    return std::hypot(std::hypot(x - 20, y - 20) - Rc, z - 7);
  };
  const auto torus = shape(g, [&](int i, int j, int k) { return distToCore(i, j, k) <= r; });
  const MedialAxis axis = computeMedialAxis(g, torus, MedialAxisParameters{});
  ASSERT_GT(axis.voxels.size(), 40u);
  for (uint32_t v : axis.voxels) {
    const auto c = g.coords(v);
    EXPECT_LE(distToCore(c[0], c[1], c[2]), 3.0);  // digital tube of radius 5: jitter
  }
  // The axis goes all around the core circle.
  for (int a = 0; a < 36; ++a) {
    const double t = a * M_PI / 18, x = 20 + Rc * std::cos(t), y = 20 + Rc * std::sin(t);
    double best = 1e9;
    for (uint32_t v : axis.voxels) {
      const auto c = g.coords(v);
      best = std::min(best, std::hypot(std::hypot(c[0] - x, c[1] - y), c[2] - 7));
    }
    EXPECT_LE(best, 2.0) << "gap in the torus axis at angle " << a * 10;
  }
  expectInsideWithExactRadius(g, torus, axis);
}

TEST(MedialAxis, PruningIsMonotoneInGamma) {
  const Grid3 g = grid(30, 26, 22);
  // A ball fused with a slab and a rod: curved, flat and thin parts.
  const auto blob = shape(g, [](int i, int j, int k) {
    const bool ball = (i - 10) * (i - 10) + (j - 12) * (j - 12) + (k - 11) * (k - 11) <= 64;
    const bool slab = i >= 12 && i <= 27 && j >= 3 && j <= 22 && k >= 9 && k <= 13;
    const bool rod = (j - 20) * (j - 20) + (k - 4) * (k - 4) <= 4 && i >= 3 && i <= 26;
    return ball || slab || rod;
  });
  struct Variant {
    MedialAxisPruning p;
    std::vector<double> gammas;
  };
  for (const Variant& var :
       {Variant{MedialAxisPruning::Constant, {0, 1, 2, 3, 5, 8}},
        Variant{MedialAxisPruning::Linear, {0, 0.5, 1, 1.4, 2}},
        Variant{MedialAxisPruning::SquareRoot, {0.25, 0.5, 1, 2}},
        Variant{MedialAxisPruning::ConstantLinear, {0, 0.7, 1.4, 2}}}) {
    std::set<uint32_t> previous;
    bool first = true;
    for (double gamma : var.gammas) {
      const MedialAxis a = computeMedialAxis(g, blob, prune(var.p, gamma));
      const auto cur = asSet(a);
      if (!first)
        for (uint32_t v : cur)
          ASSERT_TRUE(previous.count(v)) << medialAxisPruningName(var.p) << " gamma " << gamma
                                         << " added a voxel";
      for (uint32_t v : cur) ASSERT_TRUE(blob[v]);
      previous = cur;
      first = false;
    }
  }
  // Every variant removes something relative to the exact IMA; constant gamma <= 1 is exact.
  const auto exact = asSet(computeMedialAxis(g, blob, prune(MedialAxisPruning::None, 1)));
  EXPECT_EQ(asSet(computeMedialAxis(g, blob, prune(MedialAxisPruning::Constant, 1))), exact);
  EXPECT_LT(asSet(computeMedialAxis(g, blob, MedialAxisParameters{})).size(), exact.size() / 2);
}

TEST(MedialAxis, InvariantUnderFlipsAndPermutations) {
  // Asymmetric shape; tie rule: the FT picks one of equally near features by axis order, so the
  // axis may move at ties. Compare as sets: at least 95 % of the voxels of either set have a
  // voxel of the other within one voxel (26-neighbourhood), all within two; counts within 10 %.
  const int n[3] = {28, 24, 20};
  auto inShape = [](int i, int j, int k) {
    const bool ball = (i - 9) * (i - 9) + (j - 10) * (j - 10) + (k - 9) * (k - 9) <= 49;
    const bool box = i >= 14 && i <= 25 && j >= 4 && j <= 19 && k >= 5 && k <= 12;
    return ball || box;
  };
  const Grid3 g = grid(n[0], n[1], n[2]);
  const auto base = shape(g, inShape);
  const MedialAxis ref = computeMedialAxis(g, base, MedialAxisParameters{});
  ASSERT_GT(ref.voxels.size(), 10u);
  // transforms: permutation perm (new axis a takes old axis perm[a]) and flips on new axes
  const int perms[3][3] = {{0, 1, 2}, {2, 0, 1}, {1, 2, 0}};
  for (const auto& perm : perms)
    for (int flips = 0; flips < 8; flips += 3) {
      Grid3 h = grid(n[perm[0]], n[perm[1]], n[perm[2]]);
      auto toOld = [&](int a, int b, int c) {
        int nw[3] = {a, b, c}, old[3];
        for (int x = 0; x < 3; ++x) {
          const int val = (flips >> x) & 1 ? h.dims[x] - 1 - nw[x] : nw[x];
          old[perm[x]] = val;
        }
        return std::array<int, 3>{{old[0], old[1], old[2]}};
      };
      const auto region = shape(h, [&](int a, int b, int c) {
        const auto o = toOld(a, b, c);
        return inShape(o[0], o[1], o[2]);
      });
      const MedialAxis axis = computeMedialAxis(h, region, MedialAxisParameters{});
      std::vector<uint8_t> mapped(g.size(), 0), refMask(g.size(), 0);
      for (uint32_t v : ref.voxels) refMask[v] = 1;
      for (uint32_t v : axis.voxels) {
        const auto c = h.coords(v);
        const auto o = toOld(c[0], c[1], c[2]);
        mapped[g.index(o[0], o[1], o[2])] = 1;
      }
      auto near = [&](const std::vector<uint8_t>& mask, const std::array<int, 3>& c, int r) {
        for (int dk = -r; dk <= r; ++dk)
          for (int dj = -r; dj <= r; ++dj)
            for (int di = -r; di <= r; ++di)
              if (g.inside(c[0] + di, c[1] + dj, c[2] + dk) &&
                  mask[g.index(c[0] + di, c[1] + dj, c[2] + dk)])
                return true;
        return false;
      };
      size_t count = 0, exactSame = 0, far1 = 0;
      for (size_t v = 0; v < g.size(); ++v) {
        if (mapped[v]) {
          ++count;
          exactSame += refMask[v];
          far1 += near(refMask, g.coords(v), 1) ? 0 : 1;
          EXPECT_TRUE(near(refMask, g.coords(v), 2));
        }
        if (refMask[v]) {
          far1 += near(mapped, g.coords(v), 1) ? 0 : 1;
          EXPECT_TRUE(near(mapped, g.coords(v), 2));
        }
      }
      EXPECT_LE(far1, (count + ref.voxels.size()) / 20);
      EXPECT_NEAR(double(count), double(ref.voxels.size()), 0.1 * ref.voxels.size());
      EXPECT_GE(exactSame, size_t(0.8 * ref.voxels.size()));
    }
}

TEST(MedialAxis, DegenerateMaterials) {
  const Grid3 g = grid(9, 8, 7);
  // One voxel: the exact IMA is the voxel itself (radius 1 = distance to a neighbour centre);
  // pruning (any floor above 2 voxels) removes it: its size comes from the neighbours' axes.
  const auto dot = shape(g, [](int i, int j, int k) { return i == 4 && j == 3 && k == 3; });
  const MedialAxis exact = computeMedialAxis(g, dot, prune(MedialAxisPruning::None, 1));
  ASSERT_EQ(exact.voxels.size(), 1u);
  EXPECT_EQ(exact.voxels[0], g.index(4, 3, 3));
  EXPECT_FLOAT_EQ(exact.radius[0], 1.0f);
  EXPECT_TRUE(computeMedialAxis(g, dot, prune(MedialAxisPruning::Constant, 3)).voxels.empty());
  // Empty material: empty axis, no error.
  EXPECT_TRUE(computeMedialAxis(g, std::vector<uint8_t>(g.size(), 0), {}).voxels.empty());
  // Whole volume: outside the volume is feature, so it behaves as a box filling the volume.
  const auto all = std::vector<uint8_t>(g.size(), 1);
  const MedialAxis full = computeMedialAxis(g, all, MedialAxisParameters{});
  EXPECT_FALSE(full.voxels.empty());
  expectInsideWithExactRadius(g, all, full);
}

TEST(MedialAxis, MaterialTouchingTheBorderIsBoundedThere) {
  // Half ball cut by the plane x = 0 (the volume border): outside counts as feature (a virtual
  // feature plane at x = -1), so the half ball is a closed solid with a flat face. Its axis is
  // the surface equidistant from the flat face and the sphere (apex at x = 5.5 on the symmetry
  // line), which runs into the sharp rim: medial voxels on the border layer x = 0 exist only
  // there, at a small radius.
  const Grid3 g = grid(14, 27, 27);
  const auto half = shape(g, [](int i, int j, int k) {
    return i * i + (j - 13) * (j - 13) + (k - 13) * (k - 13) <= 144;
  });
  const MedialAxis axis = computeMedialAxis(g, half, MedialAxisParameters{});
  ASSERT_FALSE(axis.voxels.empty());
  double apex = 1e9;
  for (size_t n = 0; n < axis.voxels.size(); ++n) {
    const auto c = g.coords(axis.voxels[n]);
    apex = std::min(apex, std::hypot(std::hypot(c[0] - 5.5, c[1] - 13.0), c[2] - 13.0));
    if (c[0] == 0) {
      EXPECT_LE(axis.radius[n], 1.5f);
      EXPECT_GE(std::hypot(c[1] - 13.0, c[2] - 13.0), 10.0);  // at the rim
    }
  }
  EXPECT_LE(apex, 1.0);
  expectInsideWithExactRadius(g, half, axis);
}

TEST(MedialAxis, ThinPlates) {
  // A plate one voxel thick: the exact IMA is the whole plate (radius = one voxel, 0.5 mm here).
  // Default pruning (constant floor 3 voxels) deletes the axis of a 1-voxel plate and most of a
  // 2-voxel plate's (documented in MedialAxis.h); a 3-voxel plate keeps its mid-sheet; a floor
  // of 2.9 keeps 2-voxel plates.
  const Grid3 g = grid(24, 20, 11, 0.5);
  auto plate = [&](int thickness) {
    return shape(g, [&](int i, int j, int k) {
      return k >= 4 && k < 4 + thickness && i >= 2 && i <= 21 && j >= 2 && j <= 17;
    });
  };
  const auto p1 = plate(1), p2 = plate(2), p3 = plate(3);
  size_t plateVoxels = 0;
  for (uint8_t b : p1) plateVoxels += b;
  const MedialAxis exact = computeMedialAxis(g, p1, prune(MedialAxisPruning::None, 1));
  EXPECT_EQ(exact.voxels.size(), plateVoxels);
  for (float r : exact.radius) EXPECT_FLOAT_EQ(r, 0.5f);
  EXPECT_EQ(computeMedialAxis(g, p1, prune(MedialAxisPruning::Linear, 1.4)).voxels.size(),
            plateVoxels);
  EXPECT_TRUE(computeMedialAxis(g, p1, MedialAxisParameters{}).voxels.empty());
  MedialAxisParameters lower;
  lower.gammaConstant = 2.9;
  const size_t keptLower = computeMedialAxis(g, p2, lower).voxels.size();
  EXPECT_GE(keptLower, plateVoxels);
  // At the default floor a 2-voxel plate keeps only pairs whose (tied) features happen to be
  // diagonal (more than 3 voxels apart): a sparse, partial sheet.
  EXPECT_LT(computeMedialAxis(g, p2, MedialAxisParameters{}).voxels.size(), keptLower / 2);
  const MedialAxis mid = computeMedialAxis(g, p3, MedialAxisParameters{});
  EXPECT_GE(mid.voxels.size(), plateVoxels * 3 / 4);
  for (uint32_t v : mid.voxels) EXPECT_EQ(g.coords(v)[2], 5);
  expectInsideWithExactRadius(g, p3, mid);
}

TEST(MedialAxis, AllLabelsIncludingBackground) {
  LabelVolume vol;
  vol.dims = {{20, 18, 16}};
  vol.spacing = {{0.7, 0.5, 0.5}};
  vol.labels.assign(vol.voxelCount(), 0);
  for (int k = 0; k < 16; ++k)
    for (int j = 0; j < 18; ++j)
      for (int i = 0; i < 20; ++i) {
        int32_t l = 0;
        if (i >= 3 && i <= 16 && j >= 3 && j <= 14 && k >= 3 && k <= 12) l = 7;    // box
        if ((i - 9) * (i - 9) + (j - 9) * (j - 9) + (k - 8) * (k - 8) <= 9) l = 1000;  // inner ball
        vol.labels[vol.index(i, j, k)] = l;
      }
  const LabelMedialAxes all = computeAllMedialAxes(vol, MedialAxisParameters{}, quietContext());
  ASSERT_EQ(all.labels, (std::vector<int32_t>{0, 7, 1000}));
  size_t unionCount = 0;
  for (uint8_t b : all.unionMask) unionCount += b;
  EXPECT_EQ(unionCount, all.voxelCount());
  for (size_t a = 0; a < all.axes.size(); ++a) {
    EXPECT_FALSE(all.axes[a].voxels.empty()) << "label " << all.labels[a];
    for (uint32_t v : all.axes[a].voxels) ASSERT_EQ(vol.labels[v], all.labels[a]);
    // Same as the single-label entry point.
    EXPECT_EQ(computeLabelMedialAxis(vol, all.labels[a], {}).voxels, all.axes[a].voxels);
  }
  const auto image = all.labelImage(-1);
  for (size_t v = 0; v < image.size(); ++v)
    EXPECT_EQ(image[v] != -1, all.unionMask[v] != 0);
  EXPECT_TRUE(computeLabelMedialAxis(vol, 55, {}).voxels.empty());  // absent label
  MedialAxisParameters bad;
  bad.gamma = -1;
  EXPECT_THROW(computeAllMedialAxes(vol, bad, quietContext()), Error);
  MedialAxisPruning p;
  EXPECT_TRUE(parseMedialAxisPruning("sqrt", p));
  EXPECT_EQ(p, MedialAxisPruning::SquareRoot);
  EXPECT_FALSE(parseMedialAxisPruning("quadratic", p));
}
