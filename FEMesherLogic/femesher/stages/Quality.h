// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file Quality.h
/// Element quality (Verdict definitions, computed with vtkMeshQuality where it has them):
///  - aspect ratio  = L_max / (2*sqrt(6)*r)       1 = regular tet, "bad" above 3
///  - radius ratio  = R / (3 r)                    1 = regular tet, "bad" above 3
///  - volume (mm^3), minimum and maximum dihedral angle (degrees; regular 70.53),
///  - scaled Jacobian (1 = regular, <= 0 inverted).
/// r = inradius, R = circumradius, L_max = longest edge. Thresholds are explicit in the report.

#include <femesher/Types.h>

#include <map>
#include <string>
#include <vector>

namespace femesher {

class RunContext;

/// Per-tet metric values, one entry per tet.
struct TetQuality {
  std::vector<double> aspectRatio, radiusRatio, volume, minDihedral, maxDihedral, scaledJacobian;
};

/// Histogram with explicit bin edges (edges.size() == counts.size() + 1).
struct Histogram {
  std::vector<double> edges;
  std::vector<size_t> counts;
};

/// Summary of one metric over a set of tets.
struct MetricSummary {
  std::string name;       ///< "aspect_ratio", "radius_ratio", "volume", "min_dihedral", ...
  std::string formula;    ///< human-readable definition
  double min = 0, max = 0, mean = 0, variance = 0;
  double badThreshold = 0;  ///< the stated threshold
  bool badAbove = true;     ///< bad when value > threshold (else when < threshold)
  bool badInclusive = false;  ///< bad also when value == threshold (scaled Jacobian: <= 0)
  size_t badCount = 0;
  double badShare = 0;      ///< badCount / tets
  size_t nonFinite = 0;     ///< values that are +inf (degenerate/inverted tets); excluded from
                            ///< mean and variance, counted in the last histogram bin and as bad
  Histogram histogram;
};

/// All metrics for one material (label) or for the whole mesh (label = kExteriorLabel).
struct QualitySummary {
  int32_t label = kExteriorLabel;
  size_t tets = 0;
  std::vector<MetricSummary> metrics;  ///< aspect_ratio, radius_ratio, volume, min_dihedral,
                                       ///< max_dihedral, scaled_jacobian (in this order)
  const MetricSummary* find(const std::string& name) const;
};

struct QualityThresholds {
  double aspectRatio = 3.0;
  double radiusRatio = 3.0;
  double minDihedralDeg = 10.0;
  double maxDihedralDeg = 170.0;
  double scaledJacobian = 0.0;  ///< bad at or below
};

struct QualityReport {
  QualityThresholds thresholds;
  QualitySummary all;
  std::vector<QualitySummary> perMaterial;  ///< sorted by label
  size_t invertedTets = 0;                  ///< signed volume <= 0
  size_t minDihedralBelow5 = 0;             ///< tets with min dihedral < 5 degrees
  size_t minDihedralBelow10 = 0;            ///< ... < 10 degrees
  size_t minDihedralBelow15 = 0;            ///< ... < 15 degrees (FE-grade meshes: none)
};

/// Compute per-tet metrics (multi-threaded, direct Verdict formulas). `ctx` may be null.
/// Conventions for bad tets: a tet with signed volume <= 0 (inverted or flat) gets aspect and
/// radius ratio +inf (Verdict returns DBL_MAX for the aspect ratio of such tets); its dihedral
/// angles are those of its (unsigned) shape; scaled Jacobian keeps its sign (0 when all edges
/// vanish). Faces of zero area give a minimum dihedral of 0 and a maximum of 180 degrees.
TetQuality computeTetQuality(const TetMesh& mesh, RunContext* ctx = nullptr);

/// Summaries, histograms (`bins` bins each) and bad counts.
QualityReport summarizeQuality(const TetMesh& mesh, const TetQuality& q,
                               const QualityThresholds& thresholds = {}, int bins = 40);

/// Reference implementation through VTK's vtkMeshQuality (Verdict), one vtkTetra per tet, single
/// threaded and slow; used to cross-check the direct formulas. maxDihedral is not provided by VTK
/// and is left empty. Inverted tets follow Verdict's conventions (not the ones above).
TetQuality computeTetQualityVtk(const TetMesh& mesh);

/// Both steps.
QualityReport computeQuality(const TetMesh& mesh, RunContext& ctx,
                             const QualityThresholds& thresholds = {});

/// JSON text of the report (object; used in the run report and by `femesher quality --json`).
std::string qualityReportToJson(const QualityReport& report, bool withHistograms = true);
/// Human-readable table.
std::string qualityReportToText(const QualityReport& report);

}  // namespace femesher
