// SPDX-License-Identifier: GPL-3.0-or-later
// BrickGrid (BrickGrid.h): every read returns the dense grid's float, bit for bit; constant bricks
// keep one value; the packing does not depend on the thread count.
#include <femesher/BrickGrid.h>

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>
#include <vector>

using namespace femesher;

namespace {

bool sameBits(float a, float b) { return std::memcmp(&a, &b, sizeof(float)) == 0; }

/// A clamped distance to a sphere (constant far inside and outside, like an indicator function
/// beyond its band), a few random values and a -0 beside +0 in one otherwise constant brick.
std::vector<float> field(const std::array<int, 3>& d) {
  std::vector<float> f(size_t(d[0]) * d[1] * d[2]);
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> noise(-1.f, 1.f);
  for (int z = 0; z < d[2]; ++z)
    for (int y = 0; y < d[1]; ++y)
      for (int x = 0; x < d[0]; ++x) {
        const double r = std::sqrt(double(x - 20) * (x - 20) + double(y - 17) * (y - 17) +
                                   double(z - 15) * (z - 15));
        f[size_t(x) + size_t(d[0]) * (size_t(y) + size_t(d[1]) * size_t(z))] =
            float(std::clamp(12.0 - r, -3.0, 3.0));
      }
  for (int n = 0; n < 20; ++n) f[size_t(rng()) % f.size()] = noise(rng);
  f[0] = 0.f;   // brick (0, 0, 0) is outside the sphere: -3 everywhere but here
  f[1] = -0.f;
  return f;
}

}  // namespace

TEST(BrickGrid, ReadsEveryDenseValueBitForBit) {
  const std::array<int, 3> d{{45, 37, 29}};  // partial bricks on every axis
  const std::vector<float> dense = field(d);
  const BrickGrid g(dense, d, 2);
  EXPECT_EQ(g.dims(), d);
  size_t differing = 0, cells = 0, cellDiffering = 0, inGridCells = 0;
  for (int z = 0; z < d[2]; ++z)
    for (int y = 0; y < d[1]; ++y)
      for (int x = 0; x < d[0]; ++x) {
        const size_t i = size_t(x) + size_t(d[0]) * (size_t(y) + size_t(d[1]) * size_t(z));
        differing += !sameBits(g.at(x, y, z), dense[i]);
        double c[8], any[8];
        const bool inGrid = x + 1 < d[0] && y + 1 < d[1] && z + 1 < d[2];
        inGridCells += g.cellInGrid(x, y, z, any);
        if (inGrid)
          for (int k = 0; k < 8; ++k)
            cellDiffering += any[k] != double(dense[size_t(x + (k & 1)) +
                                                    size_t(d[0]) * (size_t(y + ((k >> 1) & 1)) +
                                                                    size_t(d[1]) * size_t(z + ((k >> 2) & 1)))]);
        if (!g.cell(x, y, z, c)) continue;
        ++cells;
        for (int k = 0; k < 8; ++k)
          cellDiffering += c[k] != double(g.at(x + (k & 1), y + ((k >> 1) & 1), z + ((k >> 2) & 1)));
      }
  EXPECT_EQ(differing, 0u);
  EXPECT_EQ(cellDiffering, 0u);
  // A cell lies in one brick unless it crosses a brick's last row or leaves the grid.
  size_t expected = 1;
  for (int a = 0; a < 3; ++a) {
    int n = 0;
    for (int x = 0; x + 1 < d[a]; ++x) n += (x & BrickGrid::kMask) != BrickGrid::kMask;
    expected *= size_t(n);
  }
  EXPECT_EQ(cells, expected);
  // cellInGrid: every cell inside the grid, across bricks too.
  EXPECT_EQ(inGridCells, size_t(d[0] - 1) * size_t(d[1] - 1) * size_t(d[2] - 1));
  double out[8];
  EXPECT_FALSE(g.cell(-1, 0, 0, out));
  EXPECT_FALSE(g.cell(d[0] - 1, 0, 0, out));
  EXPECT_FALSE(g.cell(7, 0, 0, out));
  EXPECT_TRUE(g.cellInGrid(7, 0, 0, out));
  EXPECT_FALSE(g.cellInGrid(d[0] - 1, 0, 0, out));
  EXPECT_FALSE(g.cellInGrid(0, -1, 0, out));
  // -0 and +0 are different bits: brick (0, 0, 0) is stored, and reads them back as they were.
  EXPECT_TRUE(std::signbit(g.at(1, 0, 0)));
  EXPECT_FALSE(std::signbit(g.at(0, 0, 0)));
  const std::vector<float> back = g.dense(2);
  ASSERT_EQ(back.size(), dense.size());
  EXPECT_EQ(std::memcmp(back.data(), dense.data(), dense.size() * sizeof(float)), 0);
}

TEST(BrickGrid, ConstantBricksKeepOneValue) {
  const std::array<int, 3> d{{64, 64, 64}};
  std::vector<float> dense = field(d);
  const BrickGrid g(dense, d, 1);
  const size_t bricks = 8 * 8 * 8;
  // The sphere's band (|12 - r| < 3) and the random values touch a minority of the bricks.
  EXPECT_GT(g.storedBricks(), 20u);
  EXPECT_LT(g.storedBricks(), bricks / 2);
  EXPECT_LT(g.bytes(), dense.size() * sizeof(float) / 2);
  // A grid of one value stores no brick; its reads are that value.
  const BrickGrid flat(std::vector<float>(dense.size(), 2.5f), d, 2);
  EXPECT_EQ(flat.storedBricks(), 0u);
  EXPECT_EQ(flat.at(63, 0, 31), 2.5f);
  // One thread or two: the same bricks, the same bytes.
  const BrickGrid two(dense, d, 2);
  EXPECT_EQ(two.storedBricks(), g.storedBricks());
  EXPECT_EQ(two.dense(1), g.dense(2));
  // An empty grid.
  const BrickGrid none(std::vector<float>{}, {{0, 0, 0}}, 2);
  EXPECT_TRUE(none.empty());
  EXPECT_TRUE(none.dense(2).empty());
}
