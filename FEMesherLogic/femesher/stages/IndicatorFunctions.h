// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file IndicatorFunctions.h
/// Stage 2 ("Tightening"): one smooth indicator f_m per material m (background included), positive
/// inside. f_m is the signed Euclidean distance to m's voxel boundary (exact, anisotropic),
/// clamped to a narrow band, Gaussian-smoothed (sigma in voxels) and then constrained so the sign
/// at every voxel centre matches the label map: the smooth surfaces lose the staircase but never
/// cross a voxel centre, i.e. they move less than half a voxel.
///
/// The input volume's box bounds the domain exactly, with flat faces and sharp edges (a material
/// cut by the volume's border ends on the box, not on a surface rounded by half a voxel): each
/// f_m is computed from the labels extended past the box (every padding voxel takes the label of
/// the nearest voxel inside the box), and value(), eval() and gradient() return max(f_0, d) for
/// the outside label 0 and min(f_m, -d) for every material, d being the signed distance (mm) to
/// the box (positive outside). The sign at every voxel centre still matches the label map.
///
/// Multi-material: a point belongs to argmax_m f_m; the interface of a and b is f_a = f_b >= others.
/// Each f_m is stored only on its material's bounding box plus the band, in a BrickGrid: beyond
/// the band, where f_m is clamped, a brick of 8^3 voxels keeps one value (memory follows the
/// interfaces' area rather than the boxes' volume; the values are those of a dense box).
/// Positions are local voxel indices of the PreprocessedVolume grid.

#include <femesher/BrickGrid.h>
#include <femesher/Types.h>
#include <femesher/stages/LabelPreprocess.h>

#include <array>
#include <cstddef>
#include <vector>

namespace femesher {

class RunContext;

struct IndicatorParameters {
  double sigma = 0.3;  ///< Gaussian smoothing in voxels (0 = none); a label whose bounding box is
                       ///< thinner than 4 sigma gets sigma = a quarter of that thickness
  int band = 4;        ///< narrow band half-width in voxels; values beyond are clamped
  /// Volume-preserving correction rounds (0 = off): the corners the smooth surface cuts are given
  /// back on the faces next to them, so small labels keep their volume (preserve_volume).
  int volumeIterations = 4;
};

class IndicatorField {
 public:
  struct Box {
    std::array<int, 3> lo{{0, 0, 0}}, dims{{0, 0, 0}};
    BrickGrid f;  ///< dims samples
  };

  const PreprocessedVolume& volume() const { return *vol_; }
  /// Points the field at `volume`, which must hold the same grid as the one it was computed on
  /// (that volume moved or copied elsewhere): keeping a field beyond its run (DeferredCurving.h).
  void rebind(const PreprocessedVolume& volume) { vol_ = &volume; }
  /// Bytes of the stored samples (the bricks of each material's box plus band).
  size_t storedBytes() const {
    size_t n = 0;
    for (const Box& b : boxes_) n += b.f.bytes();
    return n;
  }
  /// Bytes the same boxes would take as dense floats.
  size_t denseBytes() const {
    size_t n = 0;
    for (const Box& b : boxes_) n += size_t(b.dims[0]) * size_t(b.dims[1]) * size_t(b.dims[2]);
    return n * sizeof(float);
  }
  int labelCount() const { return int(boxes_.size()); }  ///< compact ids 0..N

  /// f_m at a voxel centre (local index); far negative outside m's box.
  float value(int m, int i, int j, int k) const;
  /// Stored (unclipped) f_m at the 8 voxel centres of the cell whose lowest corner is (i,j,k),
  /// x fastest.
  void corners(int m, int i, int j, int k, double out[8]) const;
  /// Trilinear f_m at a continuous local index.
  double eval(int m, const Vec3& l) const;
  /// Gradient of the trilinear f_m (per local index unit). Where the volume's box clips f_m, the
  /// box's: its nearest face's normal, the mean of the faces' normals within 0.002 voxel of an
  /// edge or a corner (a particle on a corner of CGAL's 20012323 saw its normal flip between
  /// two faces' from one iteration to the next and its neighbours never settled).
  Vec3 gradient(int m, const Vec3& l) const;
  /// eval and gradient together (one lookup of the cell): f_m, its gradient in `grad` (gradient
  /// is this, without the value).
  double evalGradient(int m, const Vec3& l, Vec3& grad) const;
  /// `l` moved exactly onto the input's box when it lies within `tolerance` mm of it (clamped
  /// into the box, then onto the nearest face), else unchanged. Projections onto the box faces
  /// stop within their tolerance; snapping makes points on a box face exactly coplanar.
  Vec3 snapToBox(const Vec3& l, double tolerance) const;
  /// snapToBox with the tolerance every stage uses: 0.002 voxel of the smallest spacing, below
  /// every projection tolerance (so points on a box face are exactly coplanar).
  Vec3 snapToBox(const Vec3& l) const;
  /// argmax_m f_m among the labels of the 8 voxel centres around l (outside the grid: 0).
  int argmax(const Vec3& l) const;
  /// Labels of the 8 voxel centres around l (sorted, unique; at most 8).
  int cornerLabels(const Vec3& l, int out[8]) const;

 private:
  friend IndicatorField computeIndicatorFunctions(const PreprocessedVolume&,
                                                  const IndicatorParameters&, RunContext&);
  /// Signed distance (mm) from a local position to the input's box, positive outside; its
  /// gradient (per local index unit) in `grad` when not null. -inf when the box is unknown.
  double boxDistance(const Vec3& l, Vec3* grad) const;
  double clip(int m, double f, double d) const { return m == 0 ? std::max(f, d) : std::min(f, -d); }
  /// The stored samples and their trilinear interpolant, before the box clip.
  float valueRaw(int m, int i, int j, int k) const;
  double evalRaw(int m, const Vec3& l) const;
  /// The cell of l (lowest corner) and l's place in it.
  struct CellPlace {
    int i, j, k;
    double u, v, w;
  };
  static CellPlace placeOf(const Vec3& l);
  /// The trilinear interpolant of a cell's corners f and its gradient at (u, v, w).
  static double interpolate(const double f[8], const CellPlace& c);
  static Vec3 interpolateGradient(const double f[8], const CellPlace& c);
  const PreprocessedVolume* vol_ = nullptr;
  Vec3 boxLo_{{0, 0, 0}}, boxHi_{{0, 0, 0}};  ///< the input's box, local index units
  std::vector<Box> boxes_;
  float far_ = -1e3f;
};

/// Runs the stage (multi-threaded per line; progress per material; cancel checked).
IndicatorField computeIndicatorFunctions(const PreprocessedVolume& volume,
                                         const IndicatorParameters& params, RunContext& ctx);

/// Moves `x` (local index) onto the smooth interface f_a = f_b by Newton steps along the gradient
/// of f_a - f_b (canonical metric, steps of at most half a voxel). False when it does not
/// converge, ends more than two voxels from where it started, or lands where a third material
/// leads (the point is then not on the a-b interface).
bool moveOntoInterface(const IndicatorField& field, int a, int b, Vec3& x);

}  // namespace femesher
