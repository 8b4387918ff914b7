// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file MeshCheck.h
/// The check after Optimize that makes sure a mesh is never silently bad (issue 12, item 2):
///  - no tet of zero or negative volume is ever written. A tet is degenerate when its signed
///    volume is at most `flatVolumeRatio` x (its longest edge)^3 (so the test does not depend on
///    the unit). A degenerate tet with two or more faces on the mesh's outer boundary (faces no
///    other tet shares) is removed: its other faces lie in the same plane, so the outer boundary
///    only changes diagonal and no hole opens. Any other degenerate tet fails the run
///    (Error(MeshingFailed), naming how many, where and what to try);
///  - tets whose smallest dihedral angle is below `minDihedralWarning` are counted and the worst
///    few listed (the run's status is then "poor_elements", see RunReport.h).
/// Positions are in the mesh's frame (the run passes the canonical frame, mm); the reported
/// centroids go through `MeshCheckFrame::toReport` (the run maps them to physical LPS).

#include <femesher/Types.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace femesher {

struct MeshCheckParameters {
  /// Degrees; tets below it are counted and listed. 0 = no warning.
  double minDihedralWarning = 5.0;
  /// A tet whose signed volume is <= this x longest-edge^3 counts as flat (zero volume).
  double flatVolumeRatio = 1e-12;
  /// How many of the worst tets below the warning are listed.
  size_t worstListed = 5;
};

/// One listed tet: its centroid (in the report frame), its material as in `labels`, its angle.
struct PoorElement {
  Vec3 centroid{};
  int32_t label = 0;
  double minDihedral = 0;  ///< degrees
};

struct MeshCheckResult {
  double minDihedralWarning = 0;   ///< degrees, the threshold used (0 = off)
  size_t removedDegenerateTets = 0;
  size_t tetsBelowWarning = 0;
  double worstMinDihedral = 0;     ///< degrees, over every tet kept (0 for an empty mesh)
  std::vector<PoorElement> worst;  ///< worst first, at most worstListed
  /// Some tet is below a non-zero warning threshold: the run's status is "poor_elements".
  bool poor() const { return minDihedralWarning > 0 && tetsBelowWarning > 0; }
};

/// How the check names places and the mesh in its messages.
struct MeshCheckFrame {
  std::function<Vec3(const Vec3&)> toReport;  ///< mesh frame -> report frame (null = identity)
  std::string source;                         ///< the input's name, for the error message
};

/// Signed volume <= flatVolumeRatio x longest-edge^3 (true also for inverted tets).
bool isDegenerateTet(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d,
                     double flatVolumeRatio);

/// Checks the mesh (positively oriented tets, one label per tet) and removes degenerate tets on
/// the outer boundary as described above; points no tet uses any more are dropped (indices
/// renumbered, order kept). Throws Error(MeshingFailed) when a degenerate tet remains.
MeshCheckResult checkTetMesh(std::vector<Vec3>& points, std::vector<std::array<int32_t, 4>>& tets,
                             std::vector<int32_t>& labels, const MeshCheckParameters& params,
                             const MeshCheckFrame& frame = {});

/// One line for people: "worst dihedral angle 3.21 deg; 12 tets below min_dihedral_warning
/// (5 deg): status poor_elements" (or "...: status ok").
std::string meshCheckSummary(const MeshCheckResult& result);

/// The run's warning when result.poor(): "Poor elements: " + meshCheckSummary(result).
std::string poorElementsWarning(const MeshCheckResult& result);

}  // namespace femesher
