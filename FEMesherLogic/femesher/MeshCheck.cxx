// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/MeshCheck.h>

#include <femesher/Status.h>
#include <femesher/VecMath.h>
#include <femesher/stages/Optimize.h>

#include <algorithm>
#include <cstdio>
#include <map>

namespace femesher {

namespace {

using Tet = std::array<int32_t, 4>;
using Face = std::array<int32_t, 3>;

Face sortedFace(const Tet& t, int skip) {
  Face f{};
  int k = 0;
  for (int i = 0; i < 4; ++i)
    if (i != skip) f[size_t(k++)] = t[size_t(i)];
  std::sort(f.begin(), f.end());
  return f;
}

Vec3 centroidOf(const std::vector<Vec3>& p, const Tet& t) {
  Vec3 c{0, 0, 0};
  for (int32_t v : t) c = add(c, p[size_t(v)]);
  return scale(c, 0.25);
}

/// Signed volume over longest-edge^3 (0 when every edge vanishes).
double relativeVolume(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  const double vol = dot(sub(b, a), cross(sub(c, a), sub(d, a))) / 6.0;
  const Vec3* v[4] = {&a, &b, &c, &d};
  double longest = 0;
  for (int i = 0; i < 4; ++i)
    for (int j = i + 1; j < 4; ++j) longest = std::max(longest, norm(sub(*v[i], *v[j])));
  const double l3 = longest * longest * longest;
  return l3 > 0 ? vol / l3 : 0.0;
}

/// Removes degenerate tets with two or more faces on the outer boundary, repeatedly (a removal
/// can put a neighbouring flat tet on the boundary); flags them in `removed`, returns how many.
size_t peelBoundaryDegenerates(const std::vector<Tet>& tets, const std::vector<size_t>& degenerate,
                               std::vector<char>& removed) {
  std::map<Face, int> faceUse;  // only the faces of degenerate tets
  for (size_t t : degenerate)
    for (int k = 0; k < 4; ++k) faceUse[sortedFace(tets[t], k)] = 0;
  for (const Tet& t : tets)
    for (int k = 0; k < 4; ++k)
      if (auto it = faceUse.find(sortedFace(t, k)); it != faceUse.end()) ++it->second;
  size_t count = 0;
  for (bool changed = true; changed;) {
    changed = false;
    for (size_t t : degenerate) {
      if (removed[t]) continue;
      int onBoundary = 0;
      for (int k = 0; k < 4; ++k) onBoundary += faceUse[sortedFace(tets[t], k)] == 1;
      if (onBoundary < 2) continue;
      removed[t] = 1;
      for (int k = 0; k < 4; ++k) --faceUse[sortedFace(tets[t], k)];
      ++count;
      changed = true;
    }
  }
  return count;
}

std::string formatPoint(const Vec3& p) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "(%.2f, %.2f, %.2f)", p[0], p[1], p[2]);
  return buf;
}

[[noreturn]] void failDegenerate(const std::vector<Vec3>& points, const std::vector<Tet>& tets,
                                 const std::vector<size_t>& left, const std::vector<double>& rel,
                                 const MeshCheckFrame& frame) {
  size_t worst = left.front();
  for (size_t t : left)
    if (rel[t] < rel[worst]) worst = t;
  Vec3 c = centroidOf(points, tets[worst]);
  if (frame.toReport) c = frame.toReport(c);
  const std::string where = frame.source.empty() ? "the mesh" : "the mesh of " + frame.source;
  throw Error(ErrorCode::MeshingFailed,
              std::to_string(left.size()) + " tet(s) of zero or negative volume remain inside " +
                  where + " (the worst at " + formatPoint(c) +
                  " mm LPS); no mesh is written. Try a smaller target_edge_length or "
                  "facet_distance, or another seed.");
}

void listWorst(const std::vector<Vec3>& points, const std::vector<Tet>& tets,
               const std::vector<int32_t>& labels, const std::vector<double>& angle,
               const MeshCheckParameters& params, const MeshCheckFrame& frame,
               MeshCheckResult& r) {
  std::vector<size_t> below;
  for (size_t t = 0; t < tets.size(); ++t)
    if (angle[t] < params.minDihedralWarning) below.push_back(t);
  r.tetsBelowWarning = below.size();
  const size_t n = std::min(below.size(), params.worstListed);
  std::partial_sort(below.begin(), below.begin() + std::ptrdiff_t(n), below.end(),
                    [&](size_t a, size_t b) {
                      return angle[a] < angle[b] || (angle[a] == angle[b] && a < b);
                    });
  for (size_t i = 0; i < n; ++i) {
    const size_t t = below[i];
    Vec3 c = centroidOf(points, tets[t]);
    if (frame.toReport) c = frame.toReport(c);
    r.worst.push_back({c, labels[t], angle[t]});
  }
}

}  // namespace

bool isDegenerateTet(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d,
                     double flatVolumeRatio) {
  return relativeVolume(a, b, c, d) <= flatVolumeRatio;
}

MeshCheckResult checkTetMesh(std::vector<Vec3>& points, std::vector<Tet>& tets,
                             std::vector<int32_t>& labels, const MeshCheckParameters& params,
                             const MeshCheckFrame& frame) {
  MeshCheckResult r;
  r.minDihedralWarning = params.minDihedralWarning;
  std::vector<double> rel(tets.size());
  std::vector<size_t> degenerate;
  for (size_t t = 0; t < tets.size(); ++t) {
    const Tet& k = tets[t];
    rel[t] = relativeVolume(points[size_t(k[0])], points[size_t(k[1])], points[size_t(k[2])],
                            points[size_t(k[3])]);
    if (rel[t] <= params.flatVolumeRatio) degenerate.push_back(t);
  }
  if (!degenerate.empty()) {
    std::vector<char> removed(tets.size(), 0);
    r.removedDegenerateTets = peelBoundaryDegenerates(tets, degenerate, removed);
    std::vector<size_t> left;
    for (size_t t : degenerate)
      if (!removed[t]) left.push_back(t);
    if (!left.empty()) failDegenerate(points, tets, left, rel, frame);
    eraseTets(points, tets, labels, removed);
  }
  std::vector<double> angle(tets.size());
  for (size_t t = 0; t < tets.size(); ++t) {
    const Tet& k = tets[t];
    angle[t] = std::max(0.0, tetMinDihedral(points[size_t(k[0])], points[size_t(k[1])],
                                            points[size_t(k[2])], points[size_t(k[3])]));
  }
  r.worstMinDihedral = angle.empty() ? 0.0 : *std::min_element(angle.begin(), angle.end());
  if (params.minDihedralWarning > 0) listWorst(points, tets, labels, angle, params, frame, r);
  return r;
}

std::string meshCheckSummary(const MeshCheckResult& r) {
  char buf[256];
  if (r.minDihedralWarning > 0)
    std::snprintf(buf, sizeof buf,
                  "worst dihedral angle %.3g deg; %zu tet(s) below min_dihedral_warning (%g deg)",
                  r.worstMinDihedral, r.tetsBelowWarning, r.minDihedralWarning);
  else
    std::snprintf(buf, sizeof buf, "worst dihedral angle %.3g deg (min_dihedral_warning off)",
                  r.worstMinDihedral);
  std::string s = buf;
  if (r.removedDegenerateTets > 0)
    s += "; " + std::to_string(r.removedDegenerateTets) + " flat boundary tet(s) removed";
  return s + ": status " + (r.poor() ? "poor_elements" : "ok");
}

std::string poorElementsWarning(const MeshCheckResult& result) {
  return "Poor elements: " + meshCheckSummary(result);
}

}  // namespace femesher
