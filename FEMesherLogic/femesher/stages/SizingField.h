// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file SizingField.h
/// Feature-adaptive sizing field: the target edge length h (mm) at every voxel of the label map.
///
/// 1. Medial axes of every label, background included (`MedialAxis.h`, pruned IMA).
/// 2. Local feature size lfs(v) = distance (mm) from voxel v to the nearest medial voxel of ANY
///    label: one more feature transform whose features are the union of the medial voxels.
/// 3. At interface voxels (a 6-neighbour carries another label, or the voxel lies on the volume
///    border and is meshed material), h0 = clamp(scale × lfs, hMin, hMax); everywhere else
///    h0 = hMax (the interior of a material is sized by its interfaces through step 4).
///    With `interfacesOnly = false` the clamp is applied at every voxel instead.
/// 4. Gradation: h(x) ≤ h(y) + L·|x − y| for every pair of 26-neighbours, enforced by forward and
///    backward raster sweeps over the 26-neighbourhood (physical step lengths) repeated until
///    nothing changes (the rows of a sweep on one wavefront j + 2k run in parallel on oneTBB,
///    with the sequential sweep's arithmetic, so the result does not depend on the threads): the result is the largest field below h0 that satisfies the bound, i.e.
///    h(x) = min_y h0(y) + L·d26(x, y) with d26 the shortest 26-neighbour path length (≥ the
///    Euclidean distance, at most ~8 % more, which only makes h smaller).
/// 3b. With `curvatureDistance` d > 0 (and the run's indicator functions), h0 at an interface
///    voxel is also at most sqrt(6 d / κ): κ is the largest principal curvature of the smooth
///    interface there, a least-squares fit of the normal curvatures that chords of 2–5 voxels in
///    four tangent directions measure; a triangle of edge h then has its centroid within about d
///    of the interface. Off by default (the medial axis already runs close to thin and strongly
///    curved parts; BioMesh3D disables its own curvature term too).
/// The result lies in [hMin, hMax].
///
/// Frame: the field lives on the label map's grid in the CANONICAL frame (mm, spacing ⊙ index),
/// x fastest, so a writer can store `h` with the input's geometry (origin, direction).

#include <femesher/BrickGrid.h>
#include <femesher/Status.h>
#include <femesher/Types.h>
#include <femesher/stages/FeatureTransform.h>
#include <femesher/stages/MedialAxis.h>

#include <cstdint>
#include <vector>

namespace femesher {

class RunContext;
class IndicatorField;

enum class SizingMode {
  Adaptive,  ///< h from the Integer Medial Axis local feature size (this stage)
  Uniform,   ///< one edge length everywhere (`uniformEdgeLength`); this stage does not run
};

/// The element size of a run: the uniform edge length every other size derives from, and the
/// adaptive field's knobs. Lengths in mm.
struct SizingParameters {
  SizingMode mode = SizingMode::Adaptive;
  /// The uniform edge length in mm; 0 = automatic: edgeLengthFactor × the mean voxel spacing, at
  /// most a quarter of the labelled box's smallest side (tiny volumes still get a few elements).
  double targetEdgeLength = 0;
  double edgeLengthFactor = 3.0;  ///< voxels (presets: coarse 6, default 3, fine 1.5)
  double scale = 1.25;     ///< ε: h = ε × lfs ("detail" knob; smaller = more detail)
  double hMin = 0;         ///< mm; 0 = auto: half the uniform edge length
  double hMax = 0;         ///< mm; 0 = auto: 2.5 × the uniform edge length
  /// Voxels: where the smooth interface bends, h0 ≤ sqrt(6 d / κ) so that a triangle's centroid
  /// stays within d of it (κ probed with chords of the candidate size; needs the indicator
  /// functions). 0 = no curvature term.
  double curvatureDistance = 0;
  double gradation = 0.4;  ///< L > 0: h grows at most L mm per mm (about 0.2–0.5)
  /// Hand the field to TetGen as point metrics so the interior follows it too (more tets); off:
  /// the interior is graded from the surface by TetGen's quality bound.
  bool volumeSizing = false;
  MedialAxisPruning pruning = MedialAxisPruning::ConstantLinear;  ///< see MedialAxis.h
  double gamma = 1.4;          ///< γ of `pruning` (MedialAxis.h defines its scaling)
  double gammaConstant = 3.0;  ///< constant floor of ConstantLinear, voxel units
  bool interfacesOnly = true;  ///< h0 from lfs at interface voxels only (see the file comment)
  int threads = 0;             ///< 0 = all hardware threads (a run sets its own)
};

/// The uniform edge length (mm) of `params` on a label map (label 0 = not labelled; a map with no
/// 0 is labelled everywhere): see SizingParameters::targetEdgeLength.
double uniformEdgeLength(const LabelVolume& volume, const SizingParameters& params);

/// The medial-axis parameters the sizing field uses (pruning, gamma, threads of `params`).
MedialAxisParameters medialAxisParameters(const SizingParameters& params);

/// Target edge length on a grid (canonical frame).
struct SizingField {
  Grid3 grid;
  std::vector<float> h;  ///< mm, grid.size() values, x fastest (empty once packed)
  /// The same values after pack(): where h is hMax or graded evenly far from the interfaces, a
  /// brick of 8^3 voxels holds one value (a run keeps its field packed).
  BrickGrid packed;
  double hMin = 0, hMax = 0;      ///< resolved bounds used
  float lowest = 0, highest = 0;  ///< the smallest and largest value of h
  size_t medialVoxels = 0;        ///< medial voxels of all labels (diagnostics)
  size_t interfaceVoxels = 0;     ///< voxels where h0 came from the lfs

  bool empty() const { return h.empty() && packed.empty(); }
  /// h at a voxel, dense or packed.
  float value(int i, int j, int k) const {
    return h.empty() ? packed.at(i, j, k) : h[grid.index(i, j, k)];
  }
  /// Trilinear interpolation at a canonical position (mm); clamped to the grid.
  float at(const Vec3& canonicalPosition) const;
  /// Moves h into `packed` (every value read afterwards is the same float; h is released).
  void pack(int threads);
  /// The values as a dense grid, x fastest (h itself, or `packed` unpacked).
  std::vector<float> values(int threads = 0) const;
};

/// Resolved bounds (auto values applied, an automatic hMin lowered to hMax when above it) for a
/// label map; throws Error(InvalidArgument) when invalid.
void resolveSizingBounds(const SizingParameters& params, const LabelVolume& volume, double& hMin,
                         double& hMax);

/// Distance (mm) from every voxel to the nearest voxel with medialMask != 0 (+inf if none).
std::vector<float> localFeatureSize(const Grid3& grid, const std::vector<uint8_t>& medialMask,
                                    int threads = 0, RunContext* ctx = nullptr);

/// Enforce h(x) ≤ h(y) + L·|x − y| for all 26-neighbour pairs (in place; values only decrease;
/// exact in double arithmetic on the stored floats). Returns the number of sweeps.
int limitGradation(const Grid3& grid, std::vector<float>& h, double gradation,
                   RunContext* ctx = nullptr);

/// The whole stage on a label map. Progress is reported as fractions of the current stage
/// (the caller begins/ends it); cancel is checked inside every loop.
/// Errors (thrown as Error): InvalidArgument (bad parameters, empty grid), Canceled.
SizingField computeSizingField(const LabelVolume& volume, const SizingParameters& params,
                               RunContext& ctx);

/// Same, from precomputed medial axes (e.g. to write both outputs of one run).
/// With `surfaces` (the run's indicator functions on the same grid), the curvature term applies.
SizingField computeSizingField(const LabelVolume& volume, const LabelMedialAxes& axes,
                               const SizingParameters& params, RunContext& ctx,
                               const IndicatorField* surfaces = nullptr);

}  // namespace femesher
