// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file SpatialHash.h
/// Small helpers shared by the sampling stages: a 64-bit mixing function (splitmix64 finaliser)
/// for seeded, order-independent priorities, and integer cell keys for hashed uniform grids.

#include <femesher/Types.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace femesher {

inline uint64_t mix64(uint64_t x) {
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

/// Integer coordinates of a grid cell.
struct CellKey {
  int64_t x, y, z;
  bool operator==(const CellKey& o) const { return x == o.x && y == o.y && z == o.z; }
};

struct CellKeyHash {
  size_t operator()(const CellKey& k) const {
    return size_t(mix64(uint64_t(k.x) * 73856093ull ^ uint64_t(k.y) * 19349663ull ^
                        uint64_t(k.z) * 83492791ull));
  }
};

/// The cell size of a uniform grid over the box [lo, hi]: `cell` (1 when not positive), grown by
/// 1.25 until the grid has at most about 8 cells per item; `dims` gets the cells per axis.
inline double uniformGridCell(const Vec3& lo, const Vec3& hi, double cell, size_t items,
                              int64_t dims[3]) {
  cell = cell > 0 ? cell : 1.0;
  for (;;) {
    double cells = 1;
    for (int a = 0; a < 3; ++a) {
      dims[a] = int64_t(std::max(0.0, hi[a] - lo[a]) / cell) + 1;
      cells *= double(dims[a]);
    }
    if (cells <= 8.0 * double(items) + 64) return cell;
    cell *= 1.25;
  }
}

/// Uniform grid of linked lists over a fixed box, for incremental insertion of points (by id)
/// and radius queries. Points outside the box go to the nearest border cell. The cell size grows
/// from the requested one until the grid has at most ~8 cells per expected point.
class PointGrid {
 public:
  PointGrid(const Vec3& lo, const Vec3& hi, double cell, size_t expectedPoints) : lo_(lo) {
    cell_ = uniformGridCell(lo, hi, cell, expectedPoints, dims_);
    head_.assign(size_t(dims_[0] * dims_[1] * dims_[2]), kEmpty);
  }
  void insert(uint32_t id, const Vec3& p) {
    if (next_.size() <= id) next_.resize(std::max<size_t>(size_t(id) + 1, 2 * next_.size()), kEmpty);
    uint32_t& h = head_[cellOf(p)];
    next_[id] = h;
    h = id;
  }
  /// Calls fn(id) for every inserted point in the cells overlapping the cube of half-side r.
  template <class F>
  void forEachNear(const Vec3& p, double r, F&& fn) const {
    int64_t a0[3], a1[3];
    for (int a = 0; a < 3; ++a) {
      a0[a] = clampIdx(p[a] - r, a);
      a1[a] = clampIdx(p[a] + r, a);
    }
    for (int64_t z = a0[2]; z <= a1[2]; ++z)
      for (int64_t y = a0[1]; y <= a1[1]; ++y)
        for (int64_t x = a0[0]; x <= a1[0]; ++x)
          for (uint32_t id = head_[size_t(x + dims_[0] * (y + dims_[1] * z))]; id != kEmpty;
               id = next_[id])
            fn(id);
  }

 private:
  static constexpr uint32_t kEmpty = ~0u;
  int64_t clampIdx(double v, int a) const {
    return std::clamp<int64_t>(int64_t(std::floor((v - lo_[a]) / cell_)), 0, dims_[a] - 1);
  }
  size_t cellOf(const Vec3& p) const {
    return size_t(clampIdx(p[0], 0) + dims_[0] * (clampIdx(p[1], 1) + dims_[1] * clampIdx(p[2], 2)));
  }
  Vec3 lo_;
  double cell_ = 1;
  int64_t dims_[3] = {1, 1, 1};
  std::vector<uint32_t> head_, next_;
};

}  // namespace femesher
