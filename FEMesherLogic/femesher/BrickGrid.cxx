// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/BrickGrid.h>
#include <femesher/Parallel.h>

#include <algorithm>
#include <cstring>

namespace femesher {

namespace {
constexpr int kChunks = 64;
}

template <class Body>
void BrickGrid::forBricks(size_t begin, size_t end, Body&& body) const {
  std::array<int, 3> from, to;
  for (size_t b = begin; b < end; ++b) {
    const size_t bx = b % size_t(bricks_[0]), by = (b / size_t(bricks_[0])) % size_t(bricks_[1]),
                 bz = b / (size_t(bricks_[0]) * size_t(bricks_[1]));
    from = {{int(bx) << kBits, int(by) << kBits, int(bz) << kBits}};
    for (int a = 0; a < 3; ++a) to[a] = std::min(dims_[a], from[a] + kBrick);
    body(b, from, to);
  }
}

BrickGrid::BrickGrid(const std::vector<float>& dense, const std::array<int, 3>& dims, int threads)
    : dims_(dims) {
  for (int a = 0; a < 3; ++a) bricks_[a] = (dims[a] + kMask) >> kBits;
  const size_t count = size_t(bricks_[0]) * size_t(bricks_[1]) * size_t(bricks_[2]);
  if (count == 0) return;
  slot_.assign(count, kUniform);
  uniform_.assign(count, 0.f);
  const size_t sy = size_t(dims[0]), sz = sy * size_t(dims[1]);
  // Which bricks hold one value, compared bit for bit (-0 and 0 differ, as they may in a sum).
  parallelFor(count, threads, [&](size_t begin, size_t end, int) {
    forBricks(begin, end, [&](size_t b, const std::array<int, 3>& from, const std::array<int, 3>& to) {
      const float first = dense[size_t(from[0]) + sy * size_t(from[1]) + sz * size_t(from[2])];
      bool same = true;
      for (int z = from[2]; z < to[2] && same; ++z)
        for (int y = from[1]; y < to[1] && same; ++y) {
          const float* row = &dense[sy * size_t(y) + sz * size_t(z)];
          for (int x = from[0]; x < to[0] && same; ++x)
            same = std::memcmp(&row[x], &first, sizeof(float)) == 0;
        }
      if (same) uniform_[b] = first;
      else slot_[b] = 0;
    });
  }, kChunks);
  uint32_t stored = 0;
  for (uint32_t& s : slot_)
    if (s != kUniform) s = stored++;
  samples_.assign(size_t(stored) * kBrickSamples, 0.f);
  parallelFor(count, threads, [&](size_t begin, size_t end, int) {
    forBricks(begin, end, [&](size_t b, const std::array<int, 3>& from, const std::array<int, 3>& to) {
      if (slot_[b] == kUniform) return;
      float* out = &samples_[size_t(slot_[b]) * kBrickSamples];
      for (int z = from[2]; z < to[2]; ++z)
        for (int y = from[1]; y < to[1]; ++y)
          for (int x = from[0]; x < to[0]; ++x)
            out[inBrick(x, y, z)] = dense[size_t(x) + sy * size_t(y) + sz * size_t(z)];
    });
  }, kChunks);
}

std::vector<float> BrickGrid::dense(int threads) const {
  const size_t sy = size_t(dims_[0]), sz = sy * size_t(dims_[1]);
  std::vector<float> out(sz * size_t(dims_[2]));
  if (slot_.empty()) return out;
  parallelFor(slot_.size(), threads, [&](size_t begin, size_t end, int) {
    forBricks(begin, end, [&](size_t, const std::array<int, 3>& from, const std::array<int, 3>& to) {
      for (int z = from[2]; z < to[2]; ++z)
        for (int y = from[1]; y < to[1]; ++y)
          for (int x = from[0]; x < to[0]; ++x)
            out[size_t(x) + sy * size_t(y) + sz * size_t(z)] = at(x, y, z);
    });
  }, kChunks);
  return out;
}

}  // namespace femesher
