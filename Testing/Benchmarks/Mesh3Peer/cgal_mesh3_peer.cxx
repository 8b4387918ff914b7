// SPDX-License-Identifier: GPL-3.0-or-later
// The peer in FEMesher's benchmark: CGAL Mesh_3 (Debian's CGAL 5.5, TBB-parallel) meshing a
// labelled image, with FEMesher's triple lines given to it as protected 1-D features (CGAL 5.5
// cannot find interior triple lines itself). It reads the label map, preprocesses it and measures
// quality and fidelity with FEMesherLogic, so both meshers are judged by the same code.
//
//   cgal_mesh3_peer IN [-o OUT.vtu] [--facet-distance MM] [--facet-size MM] [--cell-size MM]
//                   [--edge-size MM] [--no-features] [--threads N] [--min-voxels N]
// Prints one JSON object (seconds per phase, counts, quality, fidelity) on stdout.
#include <femesher/RunContext.h>
#include <femesher/Types.h>
#include <femesher/io/LabelMapIO.h>
#include <femesher/io/MeshIO.h>
#include <femesher/stages/Fidelity.h>
#include <femesher/stages/IndicatorFunctions.h>
#include <femesher/stages/Junctions.h>
#include <femesher/stages/LabelPreprocess.h>
#include <femesher/stages/Quality.h>

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Image_3.h>
#include <CGAL/Labeled_mesh_domain_3.h>
#include <CGAL/Mesh_complex_3_in_triangulation_3.h>
#include <CGAL/Mesh_criteria_3.h>
#include <CGAL/Mesh_domain_with_polyline_features_3.h>
#include <CGAL/Mesh_triangulation_3.h>
#include <CGAL/make_mesh_3.h>

#include <tbb/global_control.h>

#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <vector>

using namespace femesher;
using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using ImageDomain = CGAL::Labeled_mesh_domain_3<K>;
using MeshDomain = CGAL::Mesh_domain_with_polyline_features_3<ImageDomain>;
using Tr = CGAL::Mesh_triangulation_3<MeshDomain, CGAL::Default, CGAL::Parallel_tag>::type;
using C3t3 = CGAL::Mesh_complex_3_in_triangulation_3<Tr, MeshDomain::Corner_index,
                                                     MeshDomain::Curve_index>;
using Criteria = CGAL::Mesh_criteria_3<Tr>;
using Point = K::Point_3;
using Clock = std::chrono::steady_clock;

namespace {

double secondsSince(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

/// Triple-line particles of each label triple joined to their nearest neighbours along the line
/// (ahead and behind), as 2-point polylines in the working grid's frame (spacing x local index).
std::vector<std::vector<Point>> tripleLineSegments(const Junctions& j, const PreprocessedVolume& v,
                                                   double h) {
  std::map<std::array<uint16_t, 4>, std::vector<Vec3>> lines;
  for (const auto& p : j.particles)
    if (p.count == 3)
      lines[p.labels].push_back({p.local[0] * v.spacing[0], p.local[1] * v.spacing[1],
                                 p.local[2] * v.spacing[2]});
  std::vector<std::vector<Point>> out;
  for (const auto& [labels, pts] : lines) {
    std::set<std::pair<int, int>> done;
    for (size_t i = 0; i < pts.size(); ++i) {
      // the two nearest neighbours within 2.5 h that lie on opposite sides
      int best = -1, second = -1;
      double d1 = 1e300, d2 = 1e300;
      for (size_t k = 0; k < pts.size(); ++k) {
        if (k == i) continue;
        const double dx = pts[k][0] - pts[i][0], dy = pts[k][1] - pts[i][1], dz = pts[k][2] - pts[i][2];
        const double d = dx * dx + dy * dy + dz * dz;
        if (d > 6.25 * h * h) continue;
        if (d < d1) {
          d1 = d;
          best = int(k);
        }
      }
      if (best < 0) continue;
      const Vec3 dir{pts[best][0] - pts[i][0], pts[best][1] - pts[i][1], pts[best][2] - pts[i][2]};
      for (size_t k = 0; k < pts.size(); ++k) {
        if (k == i || int(k) == best) continue;
        const double dx = pts[k][0] - pts[i][0], dy = pts[k][1] - pts[i][1], dz = pts[k][2] - pts[i][2];
        const double d = dx * dx + dy * dy + dz * dz;
        if (d > 6.25 * h * h || dx * dir[0] + dy * dir[1] + dz * dir[2] > 0) continue;
        if (d < d2) {
          d2 = d;
          second = int(k);
        }
      }
      for (int k : {best, second})
        if (k >= 0 && done.insert({std::min(int(i), k), std::max(int(i), k)}).second)
          out.push_back({Point(pts[i][0], pts[i][1], pts[i][2]), Point(pts[k][0], pts[k][1], pts[k][2])});
    }
  }
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: cgal_mesh3_peer IN [-o OUT] [--facet-distance MM] [--facet-size MM] "
                         "[--cell-size MM] [--edge-size MM] [--no-features] [--threads N]\n");
    return 2;
  }
  std::string input = argv[1], output;
  double facetDistance = 0, facetSize = 0, cellSize = 0, edgeSize = 0;
  bool features = true;
  int threads = 0;
  int64_t minVoxels = 10;
  for (int i = 2; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() { return i + 1 < argc ? std::atof(argv[++i]) : 0.0; };
    if (a == "-o" && i + 1 < argc) output = argv[++i];
    else if (a == "--facet-distance") facetDistance = next();
    else if (a == "--facet-size") facetSize = next();
    else if (a == "--cell-size") cellSize = next();
    else if (a == "--edge-size") edgeSize = next();
    else if (a == "--no-features") features = false;
    else if (a == "--threads") threads = int(next());
    else if (a == "--min-voxels") minVoxels = int64_t(next());
    else {
      std::fprintf(stderr, "unknown option %s\n", a.c_str());
      return 2;
    }
  }
  std::unique_ptr<tbb::global_control> limit;
  if (threads > 0)
    limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                  size_t(threads));
  nlohmann::json report;
  auto t0 = Clock::now();
  auto volume = readLabelMap(input);
  if (!volume) {
    std::fprintf(stderr, "error: %s\n", volume.status().message().c_str());
    return 3;
  }
  const LabelVolume& in = volume.value();
  const double mean = (in.spacing[0] + in.spacing[1] + in.spacing[2]) / 3;
  const double smin = std::min({in.spacing[0], in.spacing[1], in.spacing[2]});
  if (facetSize <= 0) facetSize = 2 * mean;
  if (facetDistance <= 0) facetDistance = 0.5 * smin;
  if (cellSize <= 0) cellSize = 2 * facetSize;
  if (edgeSize <= 0) edgeSize = facetSize;
  RunContext ctx;
  if (threads > 0) ctx.setThreads(threads);
  LabelPreprocessParameters pp;
  pp.minVoxels = minVoxels;
  PreprocessedVolume vol = preprocessLabels(in, pp, ctx);
  report["seconds_read_preprocess"] = secondsSince(t0);

  // The image (working grid, compact labels; CGAL puts voxel centres at index x voxel size).
  auto t1 = Clock::now();
  _image* img = _createImage(size_t(vol.dims[0]), size_t(vol.dims[1]), size_t(vol.dims[2]), 1,
                             vol.spacing[0], vol.spacing[1], vol.spacing[2], 2, WK_FIXED,
                             SGN_UNSIGNED);
  std::memcpy(img->data, vol.labels.data(), vol.labels.size() * sizeof(uint16_t));
  CGAL::Image_3 image(img);
  MeshDomain domain = MeshDomain::create_labeled_image_mesh_domain(image);
  report["seconds_domain"] = secondsSince(t1);

  auto t2 = Clock::now();
  size_t featureSegments = 0;
  if (features) {
    IndicatorField field = computeIndicatorFunctions(vol, {}, ctx);
    const SizingFunction sizing = [edgeSize](const Vec3&) { return edgeSize; };
    Junctions j = findJunctions(field, sizing, {}, ctx);
    auto segments = tripleLineSegments(j, vol, edgeSize);
    featureSegments = segments.size();
    domain.add_features(segments.begin(), segments.end());
  }
  report["seconds_features"] = secondsSince(t2);
  report["feature_segments"] = featureSegments;

  auto t3 = Clock::now();
  namespace P = CGAL::parameters;
  Criteria criteria(P::edge_size = edgeSize, P::facet_angle = 30, P::facet_size = facetSize,
                    P::facet_distance = facetDistance, P::cell_radius_edge_ratio = 3,
                    P::cell_size = cellSize);
  C3t3 c3t3 = CGAL::make_mesh_3<C3t3>(domain, criteria, P::no_perturb(), P::no_exude());
  report["seconds_meshing"] = secondsSince(t3);
  auto t4 = Clock::now();
  CGAL::perturb_mesh_3(c3t3, domain, P::time_limit = 60);
  CGAL::exude_mesh_3(c3t3, P::time_limit = 60);
  report["seconds_optimisation"] = secondsSince(t4);

  // To a TetMesh in LPS with user labels.
  auto t5 = Clock::now();
  TetMesh mesh;
  std::map<Tr::Vertex_handle, int32_t> ids;
  for (auto c = c3t3.cells_in_complex_begin(); c != c3t3.cells_in_complex_end(); ++c) {
    const int sub = int(c3t3.subdomain_index(c));
    if (sub <= 0 || sub >= int(vol.userLabel.size())) continue;
    std::array<int32_t, 4> t;
    for (int k = 0; k < 4; ++k) {
      auto v = c->vertex(k);
      auto it = ids.find(v);
      if (it == ids.end()) {
        const auto& p = v->point();
        const Vec3 local{CGAL::to_double(p.x()) / vol.spacing[0], CGAL::to_double(p.y()) / vol.spacing[1],
                         CGAL::to_double(p.z()) / vol.spacing[2]};
        it = ids.emplace(v, int32_t(mesh.points.size())).first;
        mesh.points.push_back(in.canonicalToPhysical(vol.localToCanonical(local)));
      }
      t[k] = it->second;
    }
    mesh.tets.push_back(t);
    mesh.tetLabels.push_back(vol.userLabel[size_t(sub)]);
    if (mesh.tetVolume(mesh.tets.size() - 1) < 0) std::swap(mesh.tets.back()[2], mesh.tets.back()[3]);
  }
  std::set<int32_t> present(mesh.tetLabels.begin(), mesh.tetLabels.end());
  for (int32_t l : present)
    if (const Material* m = findMaterial(vol.materials, l)) mesh.materials.push_back(*m);
  report["seconds_conversion"] = secondsSince(t5);
  report["seconds_total_meshing"] = secondsSince(t0);
  if (!output.empty()) {
    Status s = writeMesh(mesh, output);
    if (!s) std::fprintf(stderr, "error: %s\n", s.message().c_str());
  }
  const QualityReport q = computeQuality(mesh, ctx);
  const FidelityReport f = computeFidelity(in, mesh, ctx);
  report["tets"] = mesh.tets.size();
  report["vertices"] = mesh.points.size();
  report["criteria"] = {{"facet_distance", facetDistance}, {"facet_size", facetSize},
                        {"cell_size", cellSize}, {"edge_size", edgeSize}, {"features", features}};
  report["quality"] = nlohmann::json::parse(qualityReportToJson(q, false));
  report["fidelity"] = nlohmann::json::parse(fidelityReportToJson(f));
  std::printf("%s\n", report.dump(2).c_str());
  return 0;
}
