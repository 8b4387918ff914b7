// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file FeatureTransform.h
/// Exact Euclidean feature transform (FT) of a 3-D grid with anisotropic spacing, in linear time.
///
/// For every voxel p the FT gives one voxel F(p) of the feature set B that minimises the squared
/// distance in the canonical frame, |S ⊙ (p − F(p))|² (S = spacing, mm). Separable algorithm of
/// Meijster, Roerdink & Hesselink (2000), carried to feature transforms as in Hesselink & Roerdink
/// (TPAMI 2008) / Maurer et al. (TPAMI 2003):
///   pass 1 (x-lines): nearest feature in the row;
///   pass 2 (y-lines) and pass 3 (z-lines): lower envelope of the parabolas
///   g(i) + S_a²·(u − i)² of the candidates found by the previous pass, minimiser read per voxel.
/// Each pass costs O(N) and is parallel over lines (std::thread).
///
/// Exactness: squared distances are evaluated everywhere with `Grid3::squaredDistance`, which
/// sums the three axis terms in the fixed order x, y, z. Because floating-point rounding of a sum
/// is monotone, the separable minimisation reproduces the brute-force minimum of that very
/// expression: the squared distance of F(p) equals the brute-force one (bit for bit when the
/// squares of the spacings are exactly representable, e.g. 1, 0.5, 0.75, 2; otherwise up to a
/// last-bit rounding difference between two mathematically tied features).
///
/// Tie rule: when several features are equally near, one of them is returned; which one depends
/// on the axis order (deterministic, independent of the thread count). Compare distances, not
/// indices.

#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

namespace femesher {

class RunContext;

/// A regular grid in the canonical frame: voxel (i,j,k) sits at spacing ⊙ (i,j,k) mm.
/// Linear index = i + dims[0]·(j + dims[1]·k) (x fastest, as in `LabelVolume`).
struct Grid3 {
  std::array<int, 3> dims{{0, 0, 0}};
  std::array<double, 3> spacing{{1, 1, 1}};  ///< mm, all > 0

  size_t size() const { return size_t(dims[0]) * size_t(dims[1]) * size_t(dims[2]); }
  size_t index(int i, int j, int k) const {
    return size_t(i) + size_t(dims[0]) * (size_t(j) + size_t(dims[1]) * size_t(k));
  }
  /// Inverse of `index`.
  std::array<int, 3> coords(size_t idx) const {
    const size_t nx = size_t(dims[0]), ny = size_t(dims[1]);
    return {{int(idx % nx), int((idx / nx) % ny), int(idx / (nx * ny))}};
  }
  bool inside(int i, int j, int k) const {
    return i >= 0 && j >= 0 && k >= 0 && i < dims[0] && j < dims[1] && k < dims[2];
  }
  /// Squared canonical distance (mm²) for an index offset; the reference formula of the FT.
  double squaredDistance(int dx, int dy, int dz) const {
    const double wx = spacing[0] * spacing[0], wy = spacing[1] * spacing[1],
                 wz = spacing[2] * spacing[2];
    return wx * double(dx) * double(dx) + wy * double(dy) * double(dy) +
           wz * double(dz) * double(dz);
  }
  double squaredDistance(size_t a, size_t b) const {
    const auto ca = coords(a), cb = coords(b);
    return squaredDistance(ca[0] - cb[0], ca[1] - cb[1], ca[2] - cb[2]);
  }
};

/// "No feature": returned for every voxel when the feature set is empty (infinitely far).
constexpr uint32_t kNoFeature = std::numeric_limits<uint32_t>::max();

/// Feature transform: for every voxel, the linear index of one nearest voxel with
/// isFeature[v] != 0, or kNoFeature when there is no feature at all.
/// \param isFeature one byte per voxel (grid.size() values).
/// \param threads   0 = all hardware threads.
/// \param ctx       optional: cancel is checked between passes and inside them.
/// \throws Error(InvalidArgument) when the mask size does not match the grid or the grid has
///         2^32 − 1 voxels or more (32-bit indices).
std::vector<uint32_t> featureTransform(const Grid3& grid, const std::vector<uint8_t>& isFeature,
                                       int threads = 0, RunContext* ctx = nullptr);

/// Squared canonical distance (mm²) from voxel `v` to its feature `f` (+inf for kNoFeature).
inline double featureSquaredDistance(const Grid3& grid, size_t v, uint32_t f) {
  if (f == kNoFeature) return std::numeric_limits<double>::infinity();
  return grid.squaredDistance(v, size_t(f));
}

/// Squared distance (mm²) of every voxel to its feature (+inf where there is none).
std::vector<double> featureSquaredDistances(const Grid3& grid, const std::vector<uint32_t>& ft,
                                            int threads = 0);

/// Euclidean distance (mm) of every voxel to its feature, as float (+inf where there is none).
std::vector<float> featureDistances(const Grid3& grid, const std::vector<uint32_t>& ft,
                                    int threads = 0);

}  // namespace femesher
