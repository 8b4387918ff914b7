// SPDX-License-Identifier: GPL-3.0-or-later
/// \file Quality.cxx
/// Tet quality with the Verdict definitions, computed directly (vtkMeshQuality through a
/// vtkUnstructuredGrid costs far more per tet than the formulas themselves; the VTK path is kept as
/// `computeTetQualityVtk` and the tests cross-check both on random tets).
///
/// For a tet (p0, p1, p2, p3): J = (p1-p0)·((p2-p0)×(p3-p0)) = 6 V (signed);
/// face normals N_f (face opposite p_f, outward for J > 0), areas A_f = |N_f|/2, S = ΣA_f;
/// inradius r = 3|V|/S; circumradius R = sqrt((P+Q+W)(P+Q-W)(P-Q+W)(-P+Q+W)) / (24|V|) with
/// P, Q, W the products of the lengths of opposite edges.
///   aspect ratio   = L_max / (2 sqrt(6) r)      (Verdict tet_aspect_ratio, Frey & George)
///   radius ratio   = R / (3 r)                  (Verdict tet_radius_ratio)
///   dihedral angle at the edge shared by faces f, g: acos(-N_f·N_g / (|N_f||N_g|))
///   scaled Jacobian = sqrt(2) J / max(λ0..λ3, |J|), λ_k = product of the 3 edge lengths at p_k.

#include <femesher/Parallel.h>
#include <femesher/RunContext.h>
#include <femesher/Status.h>
#include <femesher/stages/Quality.h>

#include <nlohmann/json.hpp>

#include <vtkCellArray.h>
#include <vtkIdList.h>
#include <vtkMeshQuality.h>
#include <vtkNew.h>
#include <vtkPoints.h>
#include <vtkTetra.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <sstream>

namespace femesher {

namespace {

constexpr double kRadToDeg = 57.29577951308232;
constexpr double kInf = std::numeric_limits<double>::infinity();

struct TetValues {
  double aspect, radius, volume, minDih, maxDih, sj;
};

inline void sub(const Vec3& a, const Vec3& b, double* o) {
  o[0] = a[0] - b[0];
  o[1] = a[1] - b[1];
  o[2] = a[2] - b[2];
}
inline void cross(const double* a, const double* b, double* o) {
  o[0] = a[1] * b[2] - a[2] * b[1];
  o[1] = a[2] * b[0] - a[0] * b[2];
  o[2] = a[0] * b[1] - a[1] * b[0];
}
inline double dot(const double* a, const double* b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

/// The Verdict formulas of the file comment; see Quality.h for the conventions on bad tets.
TetValues measure(const Vec3& p0, const Vec3& p1, const Vec3& p2, const Vec3& p3) {
  // Edges from the corners: e01, e02, e03, e12, e13, e23.
  double e01[3], e02[3], e03[3], e12[3], e13[3], e23[3];
  sub(p1, p0, e01);
  sub(p2, p0, e02);
  sub(p3, p0, e03);
  sub(p2, p1, e12);
  sub(p3, p1, e13);
  sub(p3, p2, e23);
  const double l01 = std::sqrt(dot(e01, e01)), l02 = std::sqrt(dot(e02, e02)),
               l03 = std::sqrt(dot(e03, e03)), l12 = std::sqrt(dot(e12, e12)),
               l13 = std::sqrt(dot(e13, e13)), l23 = std::sqrt(dot(e23, e23));
  // Face normals, outward for a positive tet: face k is opposite corner k.
  double N[4][3];
  cross(e12, e13, N[0]);  // (p1,p2,p3)
  cross(e03, e02, N[1]);  // (p0,p3,p2)
  cross(e01, e03, N[2]);  // (p0,p1,p3)
  cross(e02, e01, N[3]);  // (p0,p2,p1)
  double nl[4];
  for (int f = 0; f < 4; ++f) nl[f] = std::sqrt(dot(N[f], N[f]));
  double J = 0;
  {
    double c[3];
    cross(e02, e03, c);
    J = dot(e01, c);
  }
  TetValues v{};
  v.volume = J / 6.0;
  const double sumN = nl[0] + nl[1] + nl[2] + nl[3];  // = 2 S
  const double lmax = std::max({l01, l02, l03, l12, l13, l23});
  if (J > 0 && sumN > 0) {
    // r = 3V/S = J / sumN
    v.aspect = lmax * sumN / (2.0 * std::sqrt(6.0) * J);
    const double P = l01 * l23, Q = l02 * l13, W = l03 * l12;
    const double prod = (P + Q + W) * (P + Q - W) * (P - Q + W) * (-P + Q + W);
    // R = sqrt(prod) / (24 V) = sqrt(prod) / (4 J); R / (3 r) = sqrt(prod) sumN / (12 J^2)
    v.radius = std::sqrt(std::max(0.0, prod)) * sumN / (12.0 * J * J);
  } else {
    v.aspect = kInf;
    v.radius = kInf;
  }
  // Dihedral angles: faces (f, g) meet at the edge joining the two other corners.
  if (nl[0] > 0 && nl[1] > 0 && nl[2] > 0 && nl[3] > 0) {
    double cmin = 1, cmax = -1;
    for (int f = 0; f < 4; ++f)
      for (int g = f + 1; g < 4; ++g) {
        const double c = -dot(N[f], N[g]) / (nl[f] * nl[g]);
        cmin = std::min(cmin, c);
        cmax = std::max(cmax, c);
      }
    v.minDih = std::acos(std::clamp(cmax, -1.0, 1.0)) * kRadToDeg;
    v.maxDih = std::acos(std::clamp(cmin, -1.0, 1.0)) * kRadToDeg;
  } else {
    v.minDih = 0;
    v.maxDih = 180;
  }
  const double lam = std::max({l01 * l02 * l03, l01 * l12 * l13, l02 * l12 * l23, l03 * l13 * l23,
                               std::fabs(J)});
  v.sj = lam > 0 ? std::sqrt(2.0) * J / lam : 0.0;
  return v;
}

enum Metric { kAspect, kRadius, kVolume, kMinDih, kMaxDih, kSJ, kMetricCount };

const std::vector<double>& column(const TetQuality& q, int m) {
  switch (m) {
    case kAspect: return q.aspectRatio;
    case kRadius: return q.radiusRatio;
    case kVolume: return q.volume;
    case kMinDih: return q.minDihedral;
    case kMaxDih: return q.maxDihedral;
    default: return q.scaledJacobian;
  }
}

struct MetricDef {
  const char* name;
  const char* formula;
  double lo, hi;  ///< histogram range (volume: hi set from the data)
  bool badAbove, inclusive;
};

const MetricDef kDefs[kMetricCount] = {
    {"aspect_ratio", "L_max / (2 sqrt(6) r_in) (Verdict tet_aspect_ratio), 1 = regular", 1, 10, true,
     false},
    {"radius_ratio", "R_circ / (3 r_in) (Verdict tet_radius_ratio), 1 = regular", 1, 10, true, false},
    {"volume", "signed volume, mm^3", 0, 1, false, true},
    {"min_dihedral", "smallest dihedral angle, degrees (70.53 = regular)", 0, 180, false, false},
    {"max_dihedral", "largest dihedral angle, degrees (70.53 = regular)", 0, 180, true, false},
    {"scaled_jacobian", "sqrt(2) J / max(corner edge-length products, J), 1 = regular, <= 0 inverted",
     -1, 1, false, true},
};

double thresholdFor(int m, const QualityThresholds& t) {
  switch (m) {
    case kAspect: return t.aspectRatio;
    case kRadius: return t.radiusRatio;
    case kVolume: return 0.0;
    case kMinDih: return t.minDihedralDeg;
    case kMaxDih: return t.maxDihedralDeg;
    default: return t.scaledJacobian;
  }
}

/// Summary of metric m over `ids` (all tets when null). Histogram values outside the range go to
/// the first/last bin; +inf goes to the last bin.
MetricSummary summarize(int m, const TetQuality& q, const std::vector<size_t>* ids,
                        const QualityThresholds& th, int bins, double volumeMax) {
  const MetricDef& d = kDefs[m];
  const std::vector<double>& values = column(q, m);
  MetricSummary s;
  s.name = d.name;
  s.formula = d.formula;
  s.badThreshold = thresholdFor(m, th);
  s.badAbove = d.badAbove;
  s.badInclusive = d.inclusive;
  const double lo = d.lo, hi = m == kVolume ? (volumeMax > 0 ? volumeMax : 1.0) : d.hi;
  bins = std::max(1, bins);
  s.histogram.edges.resize(size_t(bins) + 1);
  for (int b = 0; b <= bins; ++b) s.histogram.edges[size_t(b)] = lo + (hi - lo) * b / bins;
  s.histogram.counts.assign(size_t(bins), 0);
  const size_t n = ids ? ids->size() : values.size();
  if (n == 0) return s;
  s.min = kInf;
  s.max = -kInf;
  double sum = 0;
  size_t finite = 0;
  const double scale = bins / (hi - lo);
  for (size_t k = 0; k < n; ++k) {
    const double x = values[ids ? (*ids)[k] : k];
    s.min = std::min(s.min, x);
    s.max = std::max(s.max, x);
    const bool isFinite = std::isfinite(x);
    if (isFinite) {
      sum += x;
      ++finite;
    } else {
      ++s.nonFinite;
    }
    bool bad;
    if (!isFinite)
      bad = true;
    else if (d.badAbove)
      bad = d.inclusive ? x >= s.badThreshold : x > s.badThreshold;
    else
      bad = d.inclusive ? x <= s.badThreshold : x < s.badThreshold;
    s.badCount += bad;
    int b = isFinite ? int(std::floor((x - lo) * scale)) : bins - 1;
    ++s.histogram.counts[size_t(std::clamp(b, 0, bins - 1))];
  }
  if (finite) {
    s.mean = sum / double(finite);
    double ss = 0;  // second pass: numerically stable variance (population)
    for (size_t k = 0; k < n; ++k) {
      const double x = values[ids ? (*ids)[k] : k];
      if (std::isfinite(x)) ss += (x - s.mean) * (x - s.mean);
    }
    s.variance = ss / double(finite);
  }
  s.badShare = double(s.badCount) / double(n);
  return s;
}

QualitySummary summarizeSet(int32_t label, const TetQuality& q, const std::vector<size_t>* ids,
                            const QualityThresholds& t, int bins, double volumeMax) {
  QualitySummary out;
  out.label = label;
  out.tets = ids ? ids->size() : q.volume.size();
  for (int m = 0; m < kMetricCount; ++m) out.metrics.push_back(summarize(m, q, ids, t, bins, volumeMax));
  return out;
}

nlohmann::json number(double x) {
  if (std::isfinite(x)) return x;
  if (std::isnan(x)) return nullptr;
  return x > 0 ? "inf" : "-inf";
}

nlohmann::json metricJson(const MetricSummary& m, bool withHistograms) {
  const char* when = m.badAbove ? (m.badInclusive ? "at_or_above" : "above")
                                : (m.badInclusive ? "at_or_below" : "below");
  nlohmann::json j = {{"formula", m.formula},       {"min", number(m.min)},
                      {"max", number(m.max)},       {"mean", number(m.mean)},
                      {"variance", number(m.variance)}, {"bad_threshold", m.badThreshold},
                      {"bad_when", when},           {"bad_count", m.badCount},
                      {"bad_share", m.badShare},    {"non_finite", m.nonFinite}};
  if (withHistograms)
    j["histogram"] = {{"edges", m.histogram.edges}, {"counts", m.histogram.counts},
                      {"note", "values outside the edges are counted in the first/last bin"}};
  return j;
}

nlohmann::json summaryJson(const QualitySummary& s, bool withHistograms) {
  nlohmann::json j;
  if (s.label != kExteriorLabel) j["label"] = s.label;
  j["tets"] = s.tets;
  for (const auto& m : s.metrics) j[m.name] = metricJson(m, withHistograms);
  return j;
}

}  // namespace

const MetricSummary* QualitySummary::find(const std::string& name) const {
  for (const auto& m : metrics)
    if (m.name == name) return &m;
  return nullptr;
}

TetQuality computeTetQuality(const TetMesh& mesh, RunContext* ctx) {
  TetQuality q;
  const size_t n = mesh.tets.size();
  q.aspectRatio.resize(n);
  q.radiusRatio.resize(n);
  q.volume.resize(n);
  q.minDihedral.resize(n);
  q.maxDihedral.resize(n);
  q.scaledJacobian.resize(n);
  const int32_t np = int32_t(mesh.points.size());
  // Blocks so that progress is reported (from this thread) and cancel is honoured promptly.
  const size_t block = 1 << 20;
  std::atomic<bool> badIndex{false};
  for (size_t b0 = 0; b0 < n; b0 += block) {
    const size_t b1 = std::min(n, b0 + block);
    parallelFor(b1 - b0, ctx ? ctx->threads() : 0, [&](size_t b, size_t e, int) {
      if (ctx && ctx->isCanceled()) return;
      for (size_t t = b0 + b; t < b0 + e; ++t) {
        const auto& T = mesh.tets[t];
        if (T[0] < 0 || T[1] < 0 || T[2] < 0 || T[3] < 0 || T[0] >= np || T[1] >= np ||
            T[2] >= np || T[3] >= np) {
          badIndex = true;
          return;
        }
        const TetValues v =
            measure(mesh.points[T[0]], mesh.points[T[1]], mesh.points[T[2]], mesh.points[T[3]]);
        q.aspectRatio[t] = v.aspect;
        q.radiusRatio[t] = v.radius;
        q.volume[t] = v.volume;
        q.minDihedral[t] = v.minDih;
        q.maxDihedral[t] = v.maxDih;
        q.scaledJacobian[t] = v.sj;
      }
    }, 16);
    if (badIndex)
      throw Error(ErrorCode::MeshingFailed,
                  "Quality: a tet refers to a point index outside the mesh's point list; the mesh "
                  "is corrupt (re-create or re-export it)");
    if (ctx) ctx->progress(0.8 * double(b1) / double(n));
  }
  return q;
}

TetQuality computeTetQualityVtk(const TetMesh& mesh) {
  TetQuality q;
  const size_t n = mesh.tets.size();
  q.aspectRatio.resize(n);
  q.radiusRatio.resize(n);
  q.volume.resize(n);
  q.minDihedral.resize(n);
  q.scaledJacobian.resize(n);
  vtkNew<vtkTetra> tet;
  for (size_t t = 0; t < n; ++t) {
    for (int k = 0; k < 4; ++k) {
      const Vec3& p = mesh.points[size_t(mesh.tets[t][k])];
      tet->GetPoints()->SetPoint(k, p[0], p[1], p[2]);
      tet->GetPointIds()->SetId(k, k);
    }
    q.aspectRatio[t] = vtkMeshQuality::TetAspectRatio(tet);
    q.radiusRatio[t] = vtkMeshQuality::TetRadiusRatio(tet);
    q.volume[t] = vtkMeshQuality::TetVolume(tet);
    q.minDihedral[t] = vtkMeshQuality::TetMinAngle(tet);
    q.scaledJacobian[t] = vtkMeshQuality::TetScaledJacobian(tet);
  }
  return q;
}

QualityReport summarizeQuality(const TetMesh& mesh, const TetQuality& q,
                               const QualityThresholds& thresholds, int bins) {
  QualityReport r;
  r.thresholds = thresholds;
  double volumeMax = 0;
  for (double v : q.volume) volumeMax = std::max(volumeMax, v);
  r.all = summarizeSet(kExteriorLabel, q, nullptr, thresholds, bins, volumeMax);
  std::map<int32_t, std::vector<size_t>> byLabel;
  const size_t n = q.volume.size();
  for (size_t t = 0; t < n; ++t)
    byLabel[t < mesh.tetLabels.size() ? mesh.tetLabels[t] : 0].push_back(t);
  for (const auto& [label, ids] : byLabel)
    r.perMaterial.push_back(summarizeSet(label, q, &ids, thresholds, bins, volumeMax));
  for (size_t t = 0; t < n; ++t) {
    if (!(q.volume[t] > 0)) ++r.invertedTets;
    if (q.minDihedral[t] < 5.0) ++r.minDihedralBelow5;
    if (q.minDihedral[t] < 10.0) ++r.minDihedralBelow10;
    if (q.minDihedral[t] < 15.0) ++r.minDihedralBelow15;
  }
  return r;
}

QualityReport computeQuality(const TetMesh& mesh, RunContext& ctx,
                             const QualityThresholds& thresholds) {
  const TetQuality q = computeTetQuality(mesh, &ctx);
  QualityReport r = summarizeQuality(mesh, q, thresholds);
  ctx.progress(1.0);
  return r;
}

std::string qualityReportToJson(const QualityReport& report, bool withHistograms) {
  nlohmann::json j;
  j["thresholds"] = {{"aspect_ratio_above", report.thresholds.aspectRatio},
                     {"radius_ratio_above", report.thresholds.radiusRatio},
                     {"min_dihedral_below_deg", report.thresholds.minDihedralDeg},
                     {"max_dihedral_above_deg", report.thresholds.maxDihedralDeg},
                     {"scaled_jacobian_at_or_below", report.thresholds.scaledJacobian}};
  j["conventions"] =
      "Verdict definitions; tets with signed volume <= 0 get aspect and radius ratio inf "
      "(excluded from mean/variance, counted as bad and in the last histogram bin)";
  j["all"] = summaryJson(report.all, withHistograms);
  nlohmann::json per = nlohmann::json::array();
  for (const auto& s : report.perMaterial) per.push_back(summaryJson(s, withHistograms));
  j["per_material"] = per;
  j["inverted_tets"] = report.invertedTets;
  j["min_dihedral_below_5deg"] = report.minDihedralBelow5;
  j["min_dihedral_below_10deg"] = report.minDihedralBelow10;
  j["min_dihedral_below_15deg"] = report.minDihedralBelow15;
  return j.dump(2);
}

std::string qualityReportToText(const QualityReport& report) {
  std::ostringstream os;
  char buf[320];
  auto table = [&](const QualitySummary& s) {
    std::snprintf(buf, sizeof buf, "%-16s %11s %11s %11s %11s %10s %7s  %s\n", "metric", "max",
                  "min", "avg", "variance", "# bad", "% bad", "bad when");
    os << buf;
    for (const auto& m : s.metrics) {
      const char* op = m.badAbove ? (m.badInclusive ? ">=" : ">") : (m.badInclusive ? "<=" : "<");
      std::snprintf(buf, sizeof buf, "%-16s %11.4g %11.4g %11.4g %11.4g %10zu %6.2f%%  %s %g\n",
                    m.name.c_str(), m.max, m.min, m.mean, m.variance, m.badCount,
                    100.0 * m.badShare, op, m.badThreshold);
      os << buf;
    }
  };
  std::snprintf(buf, sizeof buf,
                "All tets: %zu (%zu inverted or flat; smallest dihedral angle below 5 deg: %zu, "
                "below 10: %zu, below 15: %zu)\n",
                report.all.tets, report.invertedTets, report.minDihedralBelow5,
                report.minDihedralBelow10, report.minDihedralBelow15);
  os << buf;
  table(report.all);
  if (report.perMaterial.size() > 1) {
    for (const auto& s : report.perMaterial) {
      std::snprintf(buf, sizeof buf, "\nMaterial %d: %zu tets\n", s.label, s.tets);
      os << buf;
      table(s);
    }
  }
  os << "aspect ratio = L_max/(2 sqrt(6) r_in), radius ratio = R/(3 r_in) (Verdict; 1 = regular "
        "tet); inverted tets count as inf.\n";
  return os.str();
}

}  // namespace femesher
