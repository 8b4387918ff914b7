// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/Parallel.h>
#include <femesher/RunContext.h>
#include <femesher/Status.h>
#include <femesher/VecMath.h>
#include <femesher/stages/VolumeMesh.h>
#include <femesher/stages/internal/SpatialOrder.h>
#include <femesher/stages/internal/TetgenJobs.h>

#include <algorithm>
#include <cmath>
#include <cerrno>
#include <cstring>
#include <map>
#include <sstream>

namespace femesher {

using volume_detail::JobResult;
using volume_detail::TetgenInput;
using volume_detail::TetgenOutput;
using volume_detail::runTetgenJobs;

namespace {

double signedVolume(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  const double v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  const double w[3] = {d[0] - a[0], d[1] - a[1], d[2] - a[2]};
  return (u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0]) +
          u[2] * (v[0] * w[1] - v[1] * w[0])) / 6.0;
}


/// The whole interface surface as one TetGen problem (regions numbered by TetGen, -A).
TetgenInput wholeSurface(const BoundarySurface& s, const std::vector<double>& sizes) {
  TetgenInput in;
  in.points = s.points;
  in.triangles = s.triangles;
  std::map<std::pair<uint16_t, uint16_t>, int> ids;
  for (const auto& p : s.trianglePairs) ids.emplace(p, int(ids.size()) + 1);
  for (const auto& p : s.trianglePairs) in.markers.push_back(ids[p]);
  if (sizes.size() == s.points.size()) in.sizes = sizes;
  in.globalId.resize(s.points.size());
  for (size_t i = 0; i < s.points.size(); ++i) in.globalId[i] = int32_t(i);
  return in;
}

/// True when `x` lies inside the closed surface made of `tris` (over `pts`): the parity of the
/// triangles a fixed ray from x crosses (the ray's direction avoids the axes, so points on a box
/// face or a staircase plane do not graze triangles edge-on).
bool insideClosedSurface(const Vec3& x, const std::vector<Vec3>& pts,
                         const std::vector<std::array<int32_t, 3>>& tris) {
  const Vec3 d{0.5773502691896258, 0.5826491074912312, 0.5720514308880204};
  int crossings = 0;
  for (const auto& t : tris) {  // Moller-Trumbore, counting hits at t > 0
    const Vec3& a = pts[size_t(t[0])];
    const Vec3 e1 = sub(pts[size_t(t[1])], a), e2 = sub(pts[size_t(t[2])], a);
    const Vec3 p = cross(d, e2);
    const double det = dot(e1, p);
    if (std::fabs(det) < 1e-300) continue;  // the ray is parallel to the triangle
    const Vec3 s = sub(x, a);
    const double u = dot(s, p) / det;
    if (u < 0 || u > 1) continue;
    const Vec3 q = cross(s, e1);
    const double v = dot(d, q) / det;
    if (v < 0 || u + v > 1) continue;
    if (dot(e2, q) / det > 0) ++crossings;
  }
  return crossings % 2 == 1;
}

/// One TetGen problem per material: its interface triangles, and a hole in every cavity of
/// other materials that they enclose. With -Y the interface triangles are not split, so the
/// materials' meshes share them exactly and together form one conformal mesh.
std::vector<TetgenInput> perMaterialSurfaces(const BoundarySurface& s,
                                             const std::vector<double>& sizes, bool& unplaced) {
  std::map<std::pair<uint16_t, uint16_t>, int> ids;
  for (const auto& p : s.trianglePairs) ids.emplace(p, int(ids.size()) + 1);
  int maxLabel = 0;
  for (const auto& p : s.trianglePairs) maxLabel = std::max<int>(maxLabel, p.second);
  const auto cavities = s.delaunay->enclosedCavities(s.fromDelaunay ? 1 : 8);
  std::vector<TetgenInput> inputs;
  std::vector<int32_t> local(s.points.size(), -1);
  for (int m = 1; m <= maxLabel; ++m) {
    TetgenInput in;
    in.label = m;
    for (size_t t = 0; t < s.triangles.size(); ++t) {
      const auto& pr = s.trianglePairs[t];
      if (pr.first != m && pr.second != m) continue;
      std::array<int32_t, 3> tri;
      for (int k = 0; k < 3; ++k) {
        const int32_t g = s.triangles[t][k];
        if (local[g] < 0) {
          local[g] = int32_t(in.points.size());
          in.points.push_back(s.points[g]);
          in.globalId.push_back(g);
          if (sizes.size() == s.points.size()) in.sizes.push_back(sizes[g]);
        }
        tri[k] = local[g];
      }
      in.triangles.push_back(tri);
      in.markers.push_back(ids[pr]);
    }
    for (int32_t g : in.globalId) local[g] = -1;
    if (in.triangles.empty()) continue;
    // A hole point must lie outside this material's surface: the cavities come from the
    // labelled Delaunay's regions, and a surface built otherwise (the local Delaunay one) bounds
    // them a little differently; a point inside would carve away the whole material. Each cavity
    // takes its first candidate outside; one with none cannot be meshed per material. (The
    // Delaunay's own surface bounds its regions exactly: its first candidate is outside.)
    if (size_t(m) < cavities.size())
      for (const auto& candidates : cavities[size_t(m)]) {
        auto it = std::find_if(candidates.begin(), candidates.end(), [&](const Vec3& h) {
          return s.fromDelaunay || !insideClosedSurface(h, in.points, in.triangles);
        });
        if (it == candidates.end()) {
          unplaced = true;
          break;
        }
        in.holes.push_back(*it);
      }
    inputs.push_back(std::move(in));
  }
  return inputs;
}

/// Labels the tets of one whole-surface TetGen run: per region a volume-weighted vote of the
/// labelled Delaunay tets at the tets' centroids (without region attributes, per tet).
std::vector<int> voteLabels(const TetgenOutput& out, const std::vector<Vec3>& pts,
                            const LabelledDelaunay& delaunay, size_t& regions, RunContext& ctx) {
  const int nt = int(out.tets.size() / 4);
  const bool hasRegions = !out.regions.empty();
  std::map<int, std::map<int, double>> votes;
  std::map<int, int> sampled;
  std::vector<int> tetLabel(size_t(nt), -1);
  for (int t = 0; t < nt; ++t) {
    const int32_t* T = &out.tets[4 * size_t(t)];
    const int r = hasRegions ? int(std::lround(out.regions[size_t(t)])) : -1 - t;
    if (hasRegions && sampled[r] >= 400) continue;
    const Vec3 c{(pts[T[0]][0] + pts[T[1]][0] + pts[T[2]][0] + pts[T[3]][0]) / 4,
                 (pts[T[0]][1] + pts[T[1]][1] + pts[T[2]][1] + pts[T[3]][1]) / 4,
                 (pts[T[0]][2] + pts[T[1]][2] + pts[T[2]][2] + pts[T[3]][2]) / 4};
    const int l = delaunay.labelAt(c);
    if (hasRegions) {
      ++sampled[r];
      votes[r][l] += std::fabs(signedVolume(pts[T[0]], pts[T[1]], pts[T[2]], pts[T[3]]));
    } else {
      tetLabel[size_t(t)] = l;
    }
    if ((t & 0xFFFF) == 0) ctx.checkCancel();
  }
  regions = hasRegions ? votes.size() : 0;
  if (!hasRegions) return tetLabel;
  std::map<int, int> regionLabel;
  for (const auto& [r, v] : votes) {
    int best = 0;
    double bestW = -1;
    for (const auto& [l, w] : v)
      if (w > bestW) {
        bestW = w;
        best = l;
      }
    regionLabel[r] = best;
  }
  for (int t = 0; t < nt; ++t)
    tetLabel[size_t(t)] = regionLabel[int(std::lround(out.regions[size_t(t)]))];
  return tetLabel;
}

/// Appends TetGen's tets of `label` (or of every label but 0 when labels are per tet) to the
/// result: the input's points keep their surface index, TetGen's new points are appended.
/// Returns false when TetGen renumbered the input points (then the job cannot be merged).
bool appendTets(const TetgenInput& in, const TetgenOutput& out, const std::vector<int>* tetLabels,
                VolumeMeshResult& result, std::vector<int32_t>& globalOfPoint) {
  const size_t np = out.points.size() / 3;
  if (np < in.points.size()) return false;
  for (size_t i = 0; i < in.points.size(); ++i)
    if (out.points[3 * i] != in.points[i][0] || out.points[3 * i + 1] != in.points[i][1] ||
        out.points[3 * i + 2] != in.points[i][2])
      return false;
  std::vector<int32_t> id(np, -1);
  for (size_t i = 0; i < in.points.size(); ++i) id[i] = in.globalId[i];
  const size_t nt = out.tets.size() / 4;
  for (size_t t = 0; t < nt; ++t) {
    const int l = tetLabels ? (*tetLabels)[t] : in.label;
    if (l == 0) {
      ++result.droppedCavityTets;
      continue;
    }
    std::array<int32_t, 4> T;
    for (int k = 0; k < 4; ++k) {
      const int v = out.tets[4 * t + size_t(k)];
      if (id[size_t(v)] < 0) {  // a Steiner point of this job
        id[size_t(v)] = int32_t(globalOfPoint.size());
        globalOfPoint.push_back(-1);
        result.points.push_back({out.points[3 * size_t(v)], out.points[3 * size_t(v) + 1],
                                 out.points[3 * size_t(v) + 2]});
      }
      T[k] = id[size_t(v)];
    }
    result.tets.push_back(T);
    result.labels.push_back(l);
  }
  return true;
}

/// Keeps only the points that tets use, orients every tet positively and renumbers points and
/// tets in spatial order (internal::spatiallyRenumber: the stages after this one sweep the mesh
/// locally, and TetGen's numbering, material by material, scatters neighbours in memory).
void compactAndOrient(VolumeMeshResult& r) {
  std::vector<int32_t> newId(r.points.size(), -1);
  std::vector<Vec3> pts;
  for (auto& T : r.tets) {
    for (auto& v : T) {
      if (newId[size_t(v)] < 0) {
        newId[size_t(v)] = int32_t(pts.size());
        pts.push_back(r.points[size_t(v)]);
      }
      v = newId[size_t(v)];
    }
    if (signedVolume(pts[T[0]], pts[T[1]], pts[T[2]], pts[T[3]]) < 0) std::swap(T[2], T[3]);
  }
  r.points.swap(pts);
  internal::spatiallyRenumber(r.points, r.tets, r.labels);
}

}  // namespace

VolumeMeshResult buildVolumeMesh(const BoundarySurface& s, const VolumeMeshParameters& params,
                                 RunContext& ctx) {
  VolumeMeshResult result;
  std::ostringstream base;
  base << "pzQ";
  if (params.maxRadiusEdgeRatio > 0) {
    base << "q" << params.maxRadiusEdgeRatio;
    if (params.minDihedralAngle > 0) base << "/" << params.minDihedralAngle;
  }
  const bool sized = params.pointSizes.size() == s.points.size() && params.usePointSizes;
  const std::vector<double> noSizes;
  const std::vector<double>& sizes = sized ? params.pointSizes : noSizes;
  if (sized) base << "m";
  if (params.maxTetVolume > 0) base << "a" << params.maxTetVolume;
  base << "O" << params.optimizationLevel;
  // Guard against run-away refinement: at most 40 Steiner points per surface vertex + 1M.
  base << "S" << (40 * s.points.size() + 1000000);
  const int threads = resolveThreads(ctx.threads());

  // 1. One TetGen run per material, side by side (interfaces kept, so they fit together).
  if (params.preserveInterfaces && params.perMaterial && s.delaunay) {
    const std::string switches = base.str() + "Y";
    bool unplaced = false;
    std::vector<TetgenInput> inputs = perMaterialSurfaces(s, sizes, unplaced);
    std::sort(inputs.begin(), inputs.end(), [](const TetgenInput& a, const TetgenInput& b) {
      if (a.triangles.size() != b.triangles.size()) return a.triangles.size() > b.triangles.size();
      return a.label < b.label;
    });
    // A cavity the material's own surface does not bound where the labelled Delaunay does (no
    // candidate hole point outside it): meshed as one surface below, where TetGen finds the
    // regions itself.
    std::vector<JobResult> jobs;
    if (!unplaced) jobs = runTetgenJobs(inputs, switches, threads, ctx, 0.0, 0.9);
    std::string failure = unplaced ? "a cavity with no hole point outside the material" : "";
    for (size_t j = 0; j < jobs.size() && failure.empty(); ++j)
      if (!jobs[j].ok)
        failure = "material " + std::to_string(inputs[j].label) + ": " + jobs[j].error;
    if (failure.empty()) {
      // Merge in label order (the run order above only serves the scheduling).
      std::vector<size_t> order(inputs.size());
      for (size_t j = 0; j < order.size(); ++j) order[j] = j;
      std::sort(order.begin(), order.end(),
                [&](size_t a, size_t b) { return inputs[a].label < inputs[b].label; });
      result.points = s.points;
      std::vector<int32_t> globalOfPoint(s.points.size());
      for (size_t j : order) {
        if (!appendTets(inputs[j], jobs[j].out, nullptr, result, globalOfPoint)) {
          failure = "TetGen renumbered the surface points of material " +
                    std::to_string(inputs[j].label);
          break;
        }
        result.holePoints += inputs[j].holes.size();
      }
    }
    if (failure.empty()) {
      compactAndOrient(result);
      result.switches = switches;
      result.method = "tetgen";
      result.tetgenRuns = inputs.size();
      result.regions = inputs.size();
      ctx.progress(1.0);
      return result;
    }
    if (unplaced)
      ctx.debug("Volume meshing: " + failure + " (the surface does not bound a cavity of the "
                "labelled Delaunay); the whole surface is meshed at once.");
    else
      ctx.warn("Volume meshing per material with TetGen switches '" + switches + "' failed (" +
               failure + "); the whole surface is meshed at once instead.");
    result = VolumeMeshResult{};
  }

  // 2. The whole surface at once; TetGen numbers the regions, the labelled Delaunay names them.
  const TetgenInput whole = wholeSurface(s, sizes);
  std::vector<std::pair<std::string, std::string>> attempts;
  if (params.preserveInterfaces) attempts.emplace_back(base.str() + "AY", "tetgen");
  attempts.emplace_back(base.str() + "A", params.preserveInterfaces ? "tetgen-without-Y" : "tetgen");
  for (const auto& [switches, method] : attempts) {
    ctx.checkCancel();
    auto jobs = runTetgenJobs({whole}, switches, 1, ctx, 0.0, 0.7);
    if (!jobs[0].ok) {
      ctx.warn("Volume meshing with TetGen switches '" + switches + "' failed: " + jobs[0].error + ".");
      continue;
    }
    const TetgenOutput& out = jobs[0].out;
    std::vector<Vec3> pts(out.points.size() / 3);
    for (size_t i = 0; i < pts.size(); ++i)
      pts[i] = {out.points[3 * i], out.points[3 * i + 1], out.points[3 * i + 2]};
    const std::vector<int> labels = voteLabels(out, pts, *s.delaunay, result.regions, ctx);
    // Without Y TetGen may add points on the surface: take its point list as it is.
    TetgenInput all = whole;
    all.points.assign(pts.begin(), pts.begin() + std::ptrdiff_t(std::min(pts.size(), whole.points.size())));
    std::vector<int32_t> globalOfPoint;
    result.points = all.points;
    globalOfPoint.resize(result.points.size());
    appendTets(all, out, &labels, result, globalOfPoint);
    compactAndOrient(result);
    result.switches = switches;
    result.method = method;
    result.tetgenRuns = 1;
    if (method == "tetgen-without-Y")
      ctx.warn("Interface triangles were split by TetGen (switch Y dropped); the mesh is still "
               "conformal but interfaces have extra vertices.");
    ctx.progress(1.0);
    return result;
  }

  ctx.warn("TetGen could not mesh the interface surface; the labelled Delaunay tets of the "
           "surface samples are returned instead (no quality refinement).");
  s.delaunay->exportTets(result.points, result.tets, result.labels);
  for (auto& T : result.tets)
    if (signedVolume(result.points[T[0]], result.points[T[1]], result.points[T[2]],
                     result.points[T[3]]) < 0)
      std::swap(T[2], T[3]);
  result.method = "delaunay-fallback";
  ctx.progress(1.0);
  return result;
}

ReportCounts reportCounts(const VolumeMeshResult& r) {
  return {{"tetgen_regions", double(r.regions)},
          {"tetgen_runs", double(r.tetgenRuns)},
          {"tetgen_hole_points", double(r.holePoints)}};
}

}  // namespace femesher
