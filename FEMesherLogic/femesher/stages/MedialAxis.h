// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file MedialAxis.h
/// Integer Medial Axis (IMA) of Hesselink & Roerdink ("Euclidean skeletons of digital image and
/// volume data in linear time by the integer medial axis transform", IEEE TPAMI 30(12), 2008),
/// with the paper's three pruning variants plus the combined variant recommended for sizing.
///
/// Region and features. The region R (the material) is skeletonised; the feature set is every
/// voxel NOT in R. The computation runs on the bounding box of R grown by one voxel on every side
/// (cost follows the material's size, not the volume's). Outside the volume counts as feature:
/// a material touching the volume border is bounded there, exactly as the mesh of the labelled
/// volume is (its outer surface is the volume border). The margin voxels beyond the border are
/// virtual feature voxels; they are never reported.
///
/// IMA condition (all in the canonical frame, mm). For every 6-neighbour pair p, q = p + e with at
/// least one of them in R, fp = F(p), fq = F(q) (feature transform):
///   1. the pair spans the axis only if the INDEX distance |fp − fq|² > 1 (features that are equal
///      or grid 6-neighbours span nothing) and the pruning test below holds;
///   2. with c = ⟨S⊙(fp − fq), S⊙(fp + fq − p − q)⟩, p is marked if c ≥ 0 and q if c ≤ 0;
///   3. only marks inside R are kept.
///
/// Gamma, defined ONCE here. Lengths in the pruning tests are expressed in "voxel units" of
/// u = (s_x·s_y·s_z)^(1/3) mm (the geometric mean spacing; = the voxel size for isotropic data).
/// With D² = |S⊙(fp − fq)|²/u² (squared feature distance) and
/// R² = |S⊙((p − fp) + (q − fq))|²/(4u²) (≈ squared local radius):
///   - None:          D² > 1 only: the exact, unpruned IMA (= Constant with γ = 1).
///   - Constant:      D² > γ²  — γ in voxel units; keeps pairs whose features are > γ apart
///                    (≈ a discrete λ-medial axis with λ = γ/2).
///   - Linear:        D² > 1 + γ²·R²  — γ dimensionless ("angle-like"): keeps pairs whose
///                    features are farther apart than γ × the local radius (|fp−fq| ≳ γ·r).
///   - SquareRoot:    D² > γ·(2R + 2⟨S⊙(p − q), S⊙(fp − fq)⟩/u² + 1.5) — the paper's 3-D
///                    square-root rule (C₃ = 1.5) at γ = 1 (γ scales it).
///   - ConstantLinear: D² > max(γ_c², 1 + γ²·R²) — a constant floor γ_c (voxel units,
///                    `gammaConstant`, default 3) combined with linear pruning γ (default 1.4).
///                    Recommended for sizing (the default): a digital ball (radius 13 or 35)
///                    reduces to its centre voxel, a box keeps its mid-sheet, a cylinder and a
///                    torus their core lines. Price: parts thinner than about γ_c − 1 voxels
///                    (features fewer than γ_c apart: 1- and 2-voxel plates and rods at γ_c = 3)
///                    lose their axis; their local feature size then comes from the axes of the
///                    neighbouring labels (background included), which run in the gaps around
///                    them. For data whose important parts are that thin, lower `gammaConstant`
///                    (2.9 keeps 2-voxel plates) or use Linear.
/// More pruning (a larger γ, same variant) never adds voxels: every test is monotone in γ.
///
/// Radius: per medial voxel, the distance (mm) from its centre to its nearest feature voxel
/// centre. The digital boundary (voxel faces) is half a voxel closer than the feature centres.
///
/// Tie rule. Where two features are equally near, the feature transform picks one by axis order,
/// so under axis flips or permutations the axis can shift by one voxel at such ties (e.g. an
/// even-thickness slab has two middle rows, of which the rule may keep one or both). Counts and
/// positions agree up to one voxel; tests compare sets with that tolerance.

#include <femesher/Types.h>
#include <femesher/stages/FeatureTransform.h>

#include <cstdint>
#include <string>
#include <vector>

namespace femesher {

class RunContext;

enum class MedialAxisPruning {
  None,           ///< exact IMA (no pruning)
  Constant,       ///< γ in voxel units
  Linear,         ///< γ dimensionless
  SquareRoot,     ///< paper's rule, γ = 1 (γ scales the threshold)
  ConstantLinear  ///< constant floor `gammaConstant` + linear γ (recommended)
};

/// Parse "none", "constant", "linear", "sqrt"/"squareroot", "constant-linear"/"combined";
/// returns false when unknown.
bool parseMedialAxisPruning(const std::string& text, MedialAxisPruning& out);
const char* medialAxisPruningName(MedialAxisPruning p);

struct MedialAxisParameters {
  MedialAxisPruning pruning = MedialAxisPruning::ConstantLinear;
  /// The variant's γ (see the file comment). Suggested: Constant 3–6, Linear 1–1.5,
  /// SquareRoot 1, ConstantLinear 1.4 (the default).
  double gamma = 1.4;
  /// Constant floor of ConstantLinear, voxel units (default 3).
  double gammaConstant = 3.0;
  int threads = 0;  ///< 0 = all hardware threads
};

/// The medial axis of one region, on the full grid.
struct MedialAxis {
  std::vector<uint32_t> voxels;  ///< linear indices (full grid), sorted ascending
  std::vector<float> radius;     ///< per voxel: distance to the nearest feature centre (mm)
};

/// IMA of the region {v : inRegion[v] != 0} of `grid`. An empty region gives an empty axis.
/// A region with no feature inside its grown box cannot happen (the margin is feature).
/// `ctx` (optional) is checked for cancel.
/// \throws Error(InvalidArgument) on a size mismatch or a negative γ.
MedialAxis computeMedialAxis(const Grid3& grid, const std::vector<uint8_t>& inRegion,
                             const MedialAxisParameters& params, RunContext* ctx = nullptr);

/// Medial axes of every label of a label map, background 0 included.
struct LabelMedialAxes {
  Grid3 grid;                        ///< the label map's grid (canonical frame)
  std::vector<int32_t> labels;       ///< every label present, ascending (0 included if present)
  std::vector<MedialAxis> axes;      ///< one per entry of `labels`
  std::vector<uint8_t> unionMask;    ///< grid.size() bytes, 1 where any label's axis passes
  size_t voxelCount() const;         ///< total medial voxels over all labels
  /// A label image of the axes: the label at its medial voxels, `notMedial` elsewhere.
  std::vector<int32_t> labelImage(int32_t notMedial = -1) const;
};

/// IMA of one label of `volume` (region = voxels with that label). Label absent → empty axis.
MedialAxis computeLabelMedialAxis(const LabelVolume& volume, int32_t label,
                                  const MedialAxisParameters& params, RunContext* ctx = nullptr);

/// IMA of every label (compact or not), including the background. Progress is reported through
/// `ctx` as fractions of the current stage, from `progressFrom` to `progressTo` (the caller
/// begins/ends the stage); cancel is checked inside the loops (throws Error(Canceled)).
LabelMedialAxes computeAllMedialAxes(const LabelVolume& volume, const MedialAxisParameters& params,
                                     RunContext& ctx, double progressFrom = 0,
                                     double progressTo = 1);

}  // namespace femesher
