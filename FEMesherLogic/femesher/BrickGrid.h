// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file BrickGrid.h
/// A grid of floats stored in bricks of 8 x 8 x 8 samples: a brick whose samples are all equal
/// (bit for bit) keeps one value. For fields that are constant far from the surfaces that shape
/// them (the indicator functions beyond their band, the sizing field at its upper bound), memory
/// then follows the surfaces' area rather than the grid's volume; every read returns exactly the
/// float the dense grid held.

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace femesher {

class BrickGrid {
 public:
  static constexpr int kBits = 3, kBrick = 1 << kBits, kMask = kBrick - 1;
  static constexpr int kBrickSamples = kBrick * kBrick * kBrick;

  BrickGrid() = default;
  /// Packs `dense` (dims[0] x dims[1] x dims[2] samples, x fastest) on `threads` (as parallelFor).
  BrickGrid(const std::vector<float>& dense, const std::array<int, 3>& dims, int threads);

  const std::array<int, 3>& dims() const { return dims_; }
  bool empty() const { return slot_.empty(); }
  /// The sample at (x, y, z), 0 <= x < dims[0], ...
  float at(int x, int y, int z) const {
    const size_t b = brickOf(x, y, z);
    const uint32_t s = slot_[b];
    return s == kUniform ? uniform_[b] : samples_[size_t(s) * kBrickSamples + inBrick(x, y, z)];
  }
  /// The 8 samples of the cell whose lowest corner is (x, y, z), x fastest, when the cell lies
  /// inside the grid and inside one brick; false (nothing written) otherwise.
  bool cell(int x, int y, int z, double out[8]) const {
    if (!cellInside(x, y, z) || crossesBricks(x, y, z)) return false;
    cellOfOneBrick(x, y, z, out);
    return true;
  }
  /// The 8 samples of the cell whose lowest corner is (x, y, z), x fastest, when the cell lies
  /// inside the grid (in one brick or across bricks); false (nothing written) otherwise.
  bool cellInGrid(int x, int y, int z, double out[8]) const {
    if (!cellInside(x, y, z)) return false;
    if (!crossesBricks(x, y, z))
      cellOfOneBrick(x, y, z, out);
    else
      for (int c = 0; c < 8; ++c) out[c] = at(x + (c & 1), y + ((c >> 1) & 1), z + ((c >> 2) & 1));
    return true;
  }
  /// The dense samples again (x fastest).
  std::vector<float> dense(int threads) const;
  /// Bricks that hold their samples (the others hold one value each).
  size_t storedBricks() const { return samples_.size() / kBrickSamples; }
  size_t bytes() const {
    return slot_.capacity() * sizeof(uint32_t) +
           (uniform_.capacity() + samples_.capacity()) * sizeof(float);
  }

 private:
  static constexpr uint32_t kUniform = 0xffffffffu;
  bool cellInside(int x, int y, int z) const {
    return x >= 0 && y >= 0 && z >= 0 && x + 1 < dims_[0] && y + 1 < dims_[1] && z + 1 < dims_[2];
  }
  static bool crossesBricks(int x, int y, int z) {
    return (x & kMask) == kMask || (y & kMask) == kMask || (z & kMask) == kMask;
  }
  /// cell() for a cell inside the grid and one brick.
  void cellOfOneBrick(int x, int y, int z, double out[8]) const {
    const size_t b = brickOf(x, y, z);
    const uint32_t s = slot_[b];
    if (s == kUniform) {
      for (int c = 0; c < 8; ++c) out[c] = uniform_[b];
      return;
    }
    constexpr size_t sy = kBrick, sz = size_t(kBrick) * kBrick;
    const float* p = &samples_[size_t(s) * kBrickSamples + inBrick(x, y, z)];
    out[0] = p[0];
    out[1] = p[1];
    out[2] = p[sy];
    out[3] = p[sy + 1];
    out[4] = p[sz];
    out[5] = p[sz + 1];
    out[6] = p[sz + sy];
    out[7] = p[sz + sy + 1];
  }
  size_t brickOf(int x, int y, int z) const {
    return size_t(x >> kBits) +
           size_t(bricks_[0]) * (size_t(y >> kBits) + size_t(bricks_[1]) * size_t(z >> kBits));
  }
  static size_t inBrick(int x, int y, int z) {
    return size_t(x & kMask) + kBrick * (size_t(y & kMask) + kBrick * size_t(z & kMask));
  }
  /// Calls body(brick, from, to) for bricks [begin, end): their voxel ranges [from, to).
  template <class Body>
  void forBricks(size_t begin, size_t end, Body&& body) const;

  std::array<int, 3> dims_{{0, 0, 0}}, bricks_{{0, 0, 0}};
  std::vector<uint32_t> slot_;  ///< per brick: its place in samples_ (in bricks) or kUniform
  std::vector<float> uniform_;  ///< per brick: its one value (when kUniform)
  std::vector<float> samples_;  ///< kBrickSamples per stored brick, x fastest
};

}  // namespace femesher
