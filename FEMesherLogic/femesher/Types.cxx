// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/Status.h>
#include <femesher/Types.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <array>

namespace femesher {

namespace {

Mat3 inverse3(const Mat3& m) {
  const double a = m[0], b = m[1], c = m[2], d = m[3], e = m[4], f = m[5], g = m[6], h = m[7],
               i = m[8];
  const double det = a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g);
  const double s = 1.0 / det;
  return {{(e * i - f * h) * s, (c * h - b * i) * s, (b * f - c * e) * s,
           (f * g - d * i) * s, (a * i - c * g) * s, (c * d - a * f) * s,
           (d * h - e * g) * s, (b * g - a * h) * s, (a * e - b * d) * s}};
}

}  // namespace

std::array<double, 3> defaultLabelColor(int32_t id) {
  // Hand-picked distinct colours (anatomy-friendly first entries), then a golden-angle hue walk.
  static const double table[][3] = {
      {0.50, 0.50, 0.50}, {0.90, 0.85, 0.70}, {0.85, 0.55, 0.40}, {0.35, 0.60, 0.85},
      {0.85, 0.30, 0.30}, {0.45, 0.75, 0.40}, {0.95, 0.75, 0.20}, {0.60, 0.40, 0.75},
      {0.30, 0.75, 0.75}, {0.90, 0.50, 0.70}, {0.55, 0.45, 0.30}, {0.20, 0.40, 0.65},
      {0.75, 0.75, 0.30}, {0.40, 0.55, 0.30}, {0.95, 0.60, 0.45}, {0.50, 0.80, 0.95},
  };
  const int n = int(sizeof(table) / sizeof(table[0]));
  if (id >= 0 && id < n) return {table[id][0], table[id][1], table[id][2]};
  const double hue = std::fmod(double(id) * 0.618033988749895, 1.0) * 6.0;
  const double s = 0.6, v = 0.85, c = v * s;
  const double x = c * (1 - std::fabs(std::fmod(hue, 2.0) - 1));
  double r = 0, g = 0, b = 0;
  if (hue < 1) { r = c; g = x; }
  else if (hue < 2) { r = x; g = c; }
  else if (hue < 3) { g = c; b = x; }
  else if (hue < 4) { g = x; b = c; }
  else if (hue < 5) { r = x; b = c; }
  else { r = c; b = x; }
  const double m = v - c;
  return {r + m, g + m, b + m};
}

const Material* findMaterial(const std::vector<Material>& table, int32_t id) {
  for (const auto& m : table)
    if (m.id == id) return &m;
  return nullptr;
}

Vec3 LabelVolume::canonicalToPhysical(const Vec3& c) const {
  const Mat3& d = direction;
  return {origin[0] + d[0] * c[0] + d[1] * c[1] + d[2] * c[2],
          origin[1] + d[3] * c[0] + d[4] * c[1] + d[5] * c[2],
          origin[2] + d[6] * c[0] + d[7] * c[1] + d[8] * c[2]};
}

Vec3 LabelVolume::physicalToCanonical(const Vec3& p) const {
  const Mat3 inv = inverse3(direction);
  const Vec3 q{p[0] - origin[0], p[1] - origin[1], p[2] - origin[2]};
  return {inv[0] * q[0] + inv[1] * q[1] + inv[2] * q[2],
          inv[3] * q[0] + inv[4] * q[1] + inv[5] * q[2],
          inv[6] * q[0] + inv[7] * q[1] + inv[8] * q[2]};
}

Vec3 LabelVolume::indexToPhysical(const Vec3& ijk) const {
  return canonicalToPhysical({ijk[0] * spacing[0], ijk[1] * spacing[1], ijk[2] * spacing[2]});
}

Vec3 LabelVolume::physicalToIndex(const Vec3& p) const {
  const Vec3 c = physicalToCanonical(p);
  return {c[0] / spacing[0], c[1] / spacing[1], c[2] / spacing[2]};
}

double LabelVolume::directionDeterminant() const {
  const Mat3& m = direction;
  return m[0] * (m[4] * m[8] - m[5] * m[7]) - m[1] * (m[3] * m[8] - m[5] * m[6]) +
         m[2] * (m[3] * m[7] - m[4] * m[6]);
}

bool LabelVolume::hasNoBackground() const {
  return std::find(labels.begin(), labels.end(), 0) == labels.end();
}

double TetMesh::tetVolume(size_t t) const {
  const auto& T = tets[t];
  const Vec3 &a = points[T[0]], &b = points[T[1]], &c = points[T[2]], &d = points[T[3]];
  const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  const double v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  const double w[3] = {d[0] - a[0], d[1] - a[1], d[2] - a[2]};
  return (u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0]) +
          u[2] * (v[0] * w[1] - v[1] * w[0])) / 6.0;
}

std::vector<InterfaceTriangle> extractInterfaces(const TetMesh& mesh) {
  // Faces of a positively oriented tet (a,b,c,d), each listed with outward orientation.
  static const int kFace[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
  struct Entry {
    int32_t tet;
    int face;
    int32_t other;  ///< the tet on the other side, -1 on the boundary
  };
  // Faces bucketed by their smallest vertex (counting sort), then matched within each bucket by
  // the other two: linear, and no hash map of every face.
  const size_t nTets = mesh.tets.size();
  int32_t maxVertex = -1;
  for (const auto& T : mesh.tets)
    for (int32_t v : T) maxVertex = std::max(maxVertex, v);
  struct Slot {
    int32_t b, c;
    uint32_t face;  ///< tet * 4 + f
  };
  std::vector<uint32_t> start(size_t(maxVertex) + 2, 0);
  auto sortedFace = [&](size_t t, int f) {
    std::array<int32_t, 3> k{mesh.tets[t][kFace[f][0]], mesh.tets[t][kFace[f][1]],
                             mesh.tets[t][kFace[f][2]]};
    std::sort(k.begin(), k.end());
    return k;
  };
  for (size_t t = 0; t < nTets; ++t)
    for (int f = 0; f < 4; ++f) ++start[size_t(sortedFace(t, f)[0]) + 1];
  for (size_t v = 1; v < start.size(); ++v) start[v] += start[v - 1];
  std::vector<Slot> slots(nTets * 4);
  {
    std::vector<uint32_t> fill(start.begin(), start.end() - 1);
    for (size_t t = 0; t < nTets; ++t)
      for (int f = 0; f < 4; ++f) {
        const auto k = sortedFace(t, f);
        slots[fill[size_t(k[0])]++] = Slot{k[1], k[2], uint32_t(t * 4 + size_t(f))};
      }
  }
  std::vector<Entry> faces;
  faces.reserve(nTets * 2 + 16);
  for (size_t v = 0; v + 1 < start.size(); ++v) {
    auto first = slots.begin() + start[v], last = slots.begin() + start[v + 1];
    std::sort(first, last, [](const Slot& x, const Slot& y) {
      return x.b != y.b ? x.b < y.b : x.c != y.c ? x.c < y.c : x.face < y.face;
    });
    for (auto it = first; it != last;) {
      auto run = it;
      while (run != last && run->b == it->b && run->c == it->c) ++run;
      if (run - it > 2)
        throw Error(ErrorCode::MeshingFailed,
                    "Mesh is not conformal: a triangle is shared by more than two tets");
      faces.push_back(Entry{int32_t(it->face / 4), int(it->face % 4),
                            run - it == 2 ? int32_t((it + 1)->face / 4) : -1});
      it = run;
    }
  }
  std::vector<InterfaceTriangle> out;
  for (const Entry& e : faces) {
    const int32_t la = mesh.tetLabels[e.tet];
    const int32_t lb = e.other >= 0 ? mesh.tetLabels[e.other] : kExteriorLabel;
    if (e.other >= 0 && la == lb) continue;
    InterfaceTriangle tri;
    const auto& T = mesh.tets[e.tet];
    tri.v = {T[kFace[e.face][0]], T[kFace[e.face][1]], T[kFace[e.face][2]]};
    tri.labelA = la;
    tri.labelB = lb;
    tri.tetA = e.tet;
    tri.tetB = e.other;
    if (lb != kExteriorLabel && lb < la) {
      // Re-orient so that labelA < labelB and the normal points out of labelA.
      std::swap(tri.labelA, tri.labelB);
      std::swap(tri.tetA, tri.tetB);
      std::swap(tri.v[1], tri.v[2]);
    }
    out.push_back(tri);
  }
  // Deterministic order: by label pair then by sorted vertices.
  std::sort(out.begin(), out.end(), [](const InterfaceTriangle& a, const InterfaceTriangle& b) {
    if (a.labelA != b.labelA) return a.labelA < b.labelA;
    if (a.labelB != b.labelB) return a.labelB < b.labelB;
    return a.v < b.v;
  });
  return out;
}

}  // namespace femesher
