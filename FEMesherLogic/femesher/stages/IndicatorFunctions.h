// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file IndicatorFunctions.h
/// Stage 2 ("Tightening"): one smooth indicator f_m per material m (background included), positive
/// inside. f_m is the signed Euclidean distance to m's voxel boundary (exact, anisotropic),
/// clamped to a narrow band, Gaussian-smoothed (sigma in voxels) and then constrained so the sign
/// at every voxel centre matches the label map: the smooth surfaces lose the staircase but never
/// cross a voxel centre, i.e. they move less than half a voxel.
///
/// Multi-material: a point belongs to argmax_m f_m; the interface of a and b is f_a = f_b >= others.
/// Each f_m is stored only on its material's bounding box plus the band (memory follows size).
/// Positions are local voxel indices of the PreprocessedVolume grid.

#include <femesher/Types.h>
#include <femesher/stages/LabelPreprocess.h>

#include <array>
#include <vector>

namespace femesher {

class RunContext;

struct IndicatorParameters {
  double sigma = 0.8;  ///< Gaussian smoothing in voxels (0 = none); a label whose bounding box is
                       ///< thinner than 4 sigma gets sigma = a quarter of that thickness
  int band = 4;        ///< narrow band half-width in voxels; values beyond are clamped
};

class IndicatorField {
 public:
  struct Box {
    std::array<int, 3> lo{{0, 0, 0}}, dims{{0, 0, 0}};
    std::vector<float> f;
  };

  const PreprocessedVolume& volume() const { return *vol_; }
  int labelCount() const { return int(boxes_.size()); }  ///< compact ids 0..N

  /// f_m at a voxel centre (local index); far negative outside m's box.
  float value(int m, int i, int j, int k) const;
  /// f_m at the 8 voxel centres of the cell whose lowest corner is (i,j,k), x fastest.
  void corners(int m, int i, int j, int k, double out[8]) const;
  /// Trilinear f_m at a continuous local index.
  double eval(int m, const Vec3& l) const;
  /// Gradient of the trilinear f_m (per local index unit).
  Vec3 gradient(int m, const Vec3& l) const;
  /// argmax_m f_m among the labels of the 8 voxel centres around l (outside the grid: 0).
  int argmax(const Vec3& l) const;
  /// Labels of the 8 voxel centres around l (sorted, unique; at most 8).
  int cornerLabels(const Vec3& l, int out[8]) const;

 private:
  friend IndicatorField computeIndicatorFunctions(const PreprocessedVolume&,
                                                  const IndicatorParameters&, RunContext&);
  const PreprocessedVolume* vol_ = nullptr;
  std::vector<Box> boxes_;
  float far_ = -1e3f;
};

/// Runs the stage (multi-threaded per line; progress per material; cancel checked).
IndicatorField computeIndicatorFunctions(const PreprocessedVolume& volume,
                                         const IndicatorParameters& params, RunContext& ctx);

}  // namespace femesher
