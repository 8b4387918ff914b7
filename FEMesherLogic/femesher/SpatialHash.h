// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file SpatialHash.h
/// Small helpers shared by the sampling stages: a 64-bit mixing function (splitmix64 finaliser)
/// for seeded, order-independent priorities, and integer cell keys for hashed uniform grids.

#include <cstddef>
#include <cstdint>

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

}  // namespace femesher
