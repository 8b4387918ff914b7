// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/Parallel.h>
#include <femesher/RunContext.h>
#include <femesher/stages/Fidelity.h>

#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Orthogonal_k_neighbor_search.h>
#include <CGAL/Search_traits_3.h>
#include <CGAL/Simple_cartesian.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <sstream>

namespace femesher {

namespace {

using SK = CGAL::Simple_cartesian<double>;
using SPoint = SK::Point_3;
using STriangle = SK::Triangle_3;
using TriIter = std::vector<STriangle>::const_iterator;
using Primitive = CGAL::AABB_triangle_primitive<SK, TriIter>;
using AabbTree = CGAL::AABB_tree<CGAL::AABB_traits<SK, Primitive>>;
using KdTraits = CGAL::Search_traits_3<SK>;
using KNN = CGAL::Orthogonal_k_neighbor_search<KdTraits>;

/// A voxel boundary face in the canonical frame: centre and normal axis.
struct Face {
  Vec3 c;
  int axis;
};

DistanceStats stats(std::vector<double>& d) {
  DistanceStats s;
  s.samples = d.size();
  if (d.empty()) return s;
  std::sort(d.begin(), d.end());
  double sum = 0;
  for (double x : d) sum += x;
  s.mean = sum / double(d.size());
  auto q = [&](double f) { return d[std::min(d.size() - 1, size_t(f * double(d.size() - 1) + 0.5))]; };
  s.median = q(0.5);
  s.p95 = q(0.95);
  s.p99 = q(0.99);
  s.max = d.back();
  return s;
}

}  // namespace

FidelityReport computeFidelity(const LabelVolume& labels, const TetMesh& mesh, RunContext* ctx) {
  FidelityReport rep;
  const auto& dims = labels.dims;
  const Vec3& sp = labels.spacing;
  rep.voxelSize = std::min({sp[0], sp[1], sp[2]});
  const double voxelVolume = sp[0] * sp[1] * sp[2];
  const size_t nv = labels.voxelCount();

  // --- Rasterise the mesh onto the voxel centres --------------------------------------------
  std::vector<Vec3> idx(mesh.points.size());
  for (size_t i = 0; i < mesh.points.size(); ++i) idx[i] = labels.physicalToIndex(mesh.points[i]);
  std::vector<int32_t> meshLabel(nv, 0);
  std::map<int32_t, double> meshVolume;
  std::map<int32_t, size_t> tetCount;
  for (size_t t = 0; t < mesh.tets.size(); ++t) {
    const auto& T = mesh.tets[t];
    meshVolume[mesh.tetLabels[t]] += std::fabs(mesh.tetVolume(t));
    ++tetCount[mesh.tetLabels[t]];
    const Vec3 &a = idx[T[0]], &b = idx[T[1]], &c = idx[T[2]], &d = idx[T[3]];
    int lo[3], hi[3];
    for (int k = 0; k < 3; ++k) {
      const double mn = std::min({a[k], b[k], c[k], d[k]}), mx = std::max({a[k], b[k], c[k], d[k]});
      lo[k] = std::max(0, int(std::ceil(mn - 1e-9)));
      hi[k] = std::min(dims[k] - 1, int(std::floor(mx + 1e-9)));
    }
    if (lo[0] > hi[0] || lo[1] > hi[1] || lo[2] > hi[2]) continue;
    // Barycentric coordinates via the inverse of [b-a, c-a, d-a].
    const double m[9] = {b[0] - a[0], c[0] - a[0], d[0] - a[0], b[1] - a[1], c[1] - a[1],
                         d[1] - a[1], b[2] - a[2], c[2] - a[2], d[2] - a[2]};
    const double det = m[0] * (m[4] * m[8] - m[5] * m[7]) - m[1] * (m[3] * m[8] - m[5] * m[6]) +
                       m[2] * (m[3] * m[7] - m[4] * m[6]);
    if (std::fabs(det) < 1e-300) continue;
    const double inv[9] = {(m[4] * m[8] - m[5] * m[7]) / det, (m[2] * m[7] - m[1] * m[8]) / det,
                           (m[1] * m[5] - m[2] * m[4]) / det, (m[5] * m[6] - m[3] * m[8]) / det,
                           (m[0] * m[8] - m[2] * m[6]) / det, (m[2] * m[3] - m[0] * m[5]) / det,
                           (m[3] * m[7] - m[4] * m[6]) / det, (m[1] * m[6] - m[0] * m[7]) / det,
                           (m[0] * m[4] - m[1] * m[3]) / det};
    const double eps = -1e-9;
    for (int z = lo[2]; z <= hi[2]; ++z)
      for (int y = lo[1]; y <= hi[1]; ++y)
        for (int x = lo[0]; x <= hi[0]; ++x) {
          const double px = x - a[0], py = y - a[1], pz = z - a[2];
          const double u = inv[0] * px + inv[1] * py + inv[2] * pz;
          const double v = inv[3] * px + inv[4] * py + inv[5] * pz;
          const double w = inv[6] * px + inv[7] * py + inv[8] * pz;
          if (u >= eps && v >= eps && w >= eps && u + v + w <= 1 - eps)
            meshLabel[labels.index(x, y, z)] = mesh.tetLabels[t];
        }
    if (ctx && (t & 0xFFFF) == 0) ctx->progress(0.4 * double(t) / double(mesh.tets.size()));
  }

  // --- Dice and volumes per label --------------------------------------------------------------
  std::map<int32_t, size_t> inLabels, inMesh, both;
  for (size_t i = 0; i < nv; ++i) {
    const int32_t a = labels.labels[i], b = meshLabel[i];
    ++inLabels[a];
    ++inMesh[b];
    if (a == b) ++both[a];
  }
  const bool noBackground = !inLabels.count(0);
  std::map<int32_t, bool> present;
  for (int32_t l : mesh.tetLabels) present[l] = true;
  for (const auto& [label, count] : inLabels) {
    if (label == 0) continue;
    MaterialFidelity f;
    f.label = label;
    const Material* mat = findMaterial(labels.materials, label);
    if (!mat) mat = findMaterial(mesh.materials, label);
    f.name = mat ? mat->name : "label " + std::to_string(label);
    f.voxels = count;
    f.meshVoxels = inMesh.count(label) ? inMesh[label] : 0;
    f.voxelVolume = double(count) * voxelVolume;
    f.meshVolume = meshVolume.count(label) ? meshVolume[label] : 0.0;
    f.volumeError = f.voxelVolume > 0 ? (f.meshVolume - f.voxelVolume) / f.voxelVolume : 0.0;
    const size_t inter = both.count(label) ? both[label] : 0;
    f.dice = count + f.meshVoxels > 0 ? 2.0 * double(inter) / double(count + f.meshVoxels) : 0.0;
    f.tets = tetCount.count(label) ? tetCount[label] : 0;
    rep.materials.push_back(f);
    if (!present.count(label)) rep.missingLabels.push_back(label);
  }
  if (ctx) ctx->progress(0.5);
  (void)noBackground;

  // --- Boundary distances --------------------------------------------------------------------
  // Label boundary faces (canonical frame): between 6-neighbours of different labels, and on the
  // volume border for labelled voxels (the mesh ends there).
  std::vector<Face> faces;
  for (int z = 0; z < dims[2]; ++z)
    for (int y = 0; y < dims[1]; ++y)
      for (int x = 0; x < dims[0]; ++x) {
        const int32_t l = labels.at(x, y, z);
        const int p[3] = {x, y, z};
        for (int a = 0; a < 3; ++a) {
          int q[3] = {x, y, z};
          q[a] += 1;
          const bool border = q[a] >= dims[a];
          const int32_t m = border ? 0 : labels.at(q[0], q[1], q[2]);
          Vec3 c{p[0] * sp[0], p[1] * sp[1], p[2] * sp[2]};
          if ((border && l != 0) || (!border && m != l)) {
            c[a] += 0.5 * sp[a];
            faces.push_back({c, a});
          }
          if (p[a] == 0 && l != 0) {
            Vec3 c0{p[0] * sp[0], p[1] * sp[1], p[2] * sp[2]};
            c0[a] -= 0.5 * sp[a];
            faces.push_back({c0, a});
          }
        }
      }
  const std::vector<InterfaceTriangle> tris = extractInterfaces(mesh);
  std::vector<Vec3> can(mesh.points.size());
  for (size_t i = 0; i < can.size(); ++i) can[i] = labels.physicalToCanonical(mesh.points[i]);
  if (ctx) ctx->progress(0.6);
  if (!faces.empty() && !tris.empty()) {
    // mesh -> labels: samples on the triangles to the nearest boundary square.
    std::vector<Vec3> samples;
    const size_t maxSamples = 2000000;
    const size_t triStride = std::max<size_t>(1, tris.size() * 7 / maxSamples);
    for (size_t t = 0; t < tris.size(); t += triStride) {
      const Vec3 &a = can[tris[t].v[0]], &b = can[tris[t].v[1]], &c = can[tris[t].v[2]];
      samples.push_back(a);
      samples.push_back({(a[0] + b[0]) / 2, (a[1] + b[1]) / 2, (a[2] + b[2]) / 2});
      samples.push_back({(a[0] + c[0]) / 2, (a[1] + c[1]) / 2, (a[2] + c[2]) / 2});
      samples.push_back({(a[0] + b[0] + c[0]) / 3, (a[1] + b[1] + c[1]) / 3, (a[2] + b[2] + c[2]) / 3});
    }
    std::vector<SPoint> centres;
    centres.reserve(faces.size());
    for (const auto& f : faces) centres.emplace_back(f.c[0], f.c[1], f.c[2]);
    KNN::Tree tree(centres.begin(), centres.end());
    auto squareDistance = [&](const Vec3& p, const SPoint& c, int axis) {
      double d2 = 0;
      const double cc[3] = {c.x(), c.y(), c.z()};
      for (int k = 0; k < 3; ++k) {
        double d = std::fabs(p[k] - cc[k]);
        if (k != axis) d = std::max(0.0, d - 0.5 * sp[k]);
        d2 += d * d;
      }
      return d2;
    };
    // Recover the axis of a centre: the coordinate that sits on a half-voxel.
    auto axisOf = [&](const SPoint& c) {
      const double cc[3] = {c.x(), c.y(), c.z()};
      int best = 0;
      double bestFrac = 1;
      for (int k = 0; k < 3; ++k) {
        const double f = std::fabs(std::fmod(cc[k] / sp[k], 1.0));
        const double off = std::fabs(f - 0.5);
        if (off < bestFrac) {
          bestFrac = off;
          best = k;
        }
      }
      return best;
    };
    std::vector<double> d1(samples.size());
    parallelFor(samples.size(), ctx ? ctx->threads() : 0, [&](size_t b, size_t e, int) {
      for (size_t i = b; i < e; ++i) {
        const SPoint q(samples[i][0], samples[i][1], samples[i][2]);
        KNN search(tree, q, 8);
        double best = 1e300;
        for (auto it = search.begin(); it != search.end(); ++it)
          best = std::min(best, squareDistance(samples[i], it->first, axisOf(it->first)));
        d1[i] = std::sqrt(best) / rep.voxelSize;
      }
    });
    rep.meshToLabels = stats(d1);
    if (ctx) ctx->progress(0.8);
    // labels -> mesh: face centres to the nearest interface triangle.
    std::vector<STriangle> tv;
    tv.reserve(tris.size());
    for (const auto& t : tris) {
      const Vec3 &a = can[t.v[0]], &b = can[t.v[1]], &c = can[t.v[2]];
      tv.emplace_back(SPoint(a[0], a[1], a[2]), SPoint(b[0], b[1], b[2]), SPoint(c[0], c[1], c[2]));
    }
    AabbTree aabb(tv.begin(), tv.end());
    aabb.accelerate_distance_queries();
    const size_t stride = std::max<size_t>(1, faces.size() / maxSamples);
    std::vector<size_t> picks;
    for (size_t i = 0; i < faces.size(); i += stride) picks.push_back(i);
    std::vector<double> d2(picks.size());
    parallelFor(picks.size(), ctx ? ctx->threads() : 0, [&](size_t b, size_t e, int) {
      for (size_t k = b; k < e; ++k) {
        const Vec3& c = faces[picks[k]].c;
        d2[k] = std::sqrt(aabb.squared_distance(SPoint(c[0], c[1], c[2]))) / rep.voxelSize;
      }
    });
    rep.labelsToMesh = stats(d2);
  }
  if (ctx) ctx->progress(1.0);
  return rep;
}

std::string fidelityReportToJson(const FidelityReport& r) {
  nlohmann::json j;
  nlohmann::json mats = nlohmann::json::array();
  for (const auto& m : r.materials)
    mats.push_back({{"label", m.label}, {"name", m.name}, {"voxels", m.voxels},
                    {"mesh_voxels", m.meshVoxels}, {"voxel_volume_mm3", m.voxelVolume},
                    {"mesh_volume_mm3", m.meshVolume}, {"volume_error", m.volumeError},
                    {"dice", m.dice}, {"tets", m.tets}});
  j["materials"] = mats;
  j["missing_labels"] = r.missingLabels;
  auto ds = [](const DistanceStats& s) {
    return nlohmann::json{{"samples", s.samples}, {"mean", s.mean}, {"median", s.median},
                          {"p95", s.p95}, {"p99", s.p99}, {"max", s.max}};
  };
  j["boundary_distance_unit"] = "voxels (min spacing)";
  j["voxel_size_mm"] = r.voxelSize;
  j["mesh_to_labels"] = ds(r.meshToLabels);
  j["labels_to_mesh"] = ds(r.labelsToMesh);
  return j.dump(2);
}

std::string fidelityReportToText(const FidelityReport& r) {
  std::ostringstream os;
  char buf[256];
  std::snprintf(buf, sizeof buf, "%-8s %-26s %10s %10s %9s %7s\n", "label", "name", "voxels",
                "tets", "vol.err", "Dice");
  os << buf;
  for (const auto& m : r.materials) {
    std::snprintf(buf, sizeof buf, "%-8d %-26.26s %10zu %10zu %+8.2f%% %7.4f\n", m.label,
                  m.name.c_str(), m.voxels, m.tets, 100.0 * m.volumeError, m.dice);
    os << buf;
  }
  std::snprintf(buf, sizeof buf,
                "boundary distance (voxels): mesh->labels mean %.3f p99 %.3f max %.3f; "
                "labels->mesh mean %.3f p99 %.3f max %.3f\n",
                r.meshToLabels.mean, r.meshToLabels.p99, r.meshToLabels.max, r.labelsToMesh.mean,
                r.labelsToMesh.p99, r.labelsToMesh.max);
  os << buf;
  if (!r.missingLabels.empty()) {
    os << "missing labels:";
    for (int32_t l : r.missingLabels) os << " " << l;
    os << "\n";
  }
  return os.str();
}

}  // namespace femesher
