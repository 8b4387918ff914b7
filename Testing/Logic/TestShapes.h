// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Generated label volumes shared by the logic tests, and the minimal input of the stages after
// the indicator functions. Each shape documents its dims, spacing, labels and what makes it
// special. Unless a function says otherwise: spacing 1 mm, origin 0, identity direction, and
// label 0 is the background. "Centred coordinates" (x, y, z) of voxel (i, j, k) are
// i - (dims[0] - 1) / 2 etc., in voxels from the volume's centre.
#include <femesher/RunContext.h>
#include <femesher/Types.h>
#include <femesher/stages/IndicatorFunctions.h>
#include <femesher/stages/LabelPreprocess.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <initializer_list>
#include <memory>
#include <set>
#include <string>

namespace femesher::test {

/// n x n x n cubes of edge h (origin `o`), each split into 6 tets around its main diagonal
/// (Kuhn subdivision: conformal across cubes). label(centroid) chooses the material.
template <class LabelFn>
inline TetMesh cubeGridMesh(int n, double h, const Vec3& o, LabelFn label) {
  TetMesh m;
  auto vid = [n](int i, int j, int k) { return int32_t(i + (n + 1) * (j + (n + 1) * k)); };
  for (int k = 0; k <= n; ++k)
    for (int j = 0; j <= n; ++j)
      for (int i = 0; i <= n; ++i) m.points.push_back({o[0] + h * i, o[1] + h * j, o[2] + h * k});
  static const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i)
        for (const auto& p : perms) {
          int c[3] = {i, j, k};
          std::array<int32_t, 4> t;
          t[0] = vid(c[0], c[1], c[2]);
          for (int s = 0; s < 3; ++s) {
            ++c[p[s]];
            t[size_t(s) + 1] = vid(c[0], c[1], c[2]);
          }
          m.tets.push_back(t);
          if (m.tetVolume(m.tets.size() - 1) < 0) std::swap(m.tets.back()[2], m.tets.back()[3]);
          Vec3 g{0, 0, 0};
          for (int32_t v : m.tets.back())
            for (int a = 0; a < 3; ++a) g[a] += m.points[size_t(v)][a] / 4;
          m.tetLabels.push_back(label(g));
        }
  std::set<int32_t> ls(m.tetLabels.begin(), m.tetLabels.end());
  for (int32_t l : ls) m.materials.push_back({l, "label " + std::to_string(l), defaultLabelColor(l)});
  return m;
}

/// A volume of `dims` voxels spaced `spacing` mm whose voxel (i, j, k) has the label
/// `label(x, y, z)` at its centred coordinates. The material table is left empty (later stages
/// name the labels "label N").
inline LabelVolume makeVolume(const std::array<int, 3>& dims, const Vec3& spacing,
                              const std::function<int32_t(double x, double y, double z)>& label) {
  LabelVolume v;
  v.dims = dims;
  v.spacing = spacing;
  v.labels.resize(v.voxelCount());
  const double cx = (dims[0] - 1) / 2.0, cy = (dims[1] - 1) / 2.0, cz = (dims[2] - 1) / 2.0;
  for (int k = 0; k < dims[2]; ++k)
    for (int j = 0; j < dims[1]; ++j)
      for (int i = 0; i < dims[0]; ++i) v.labels[v.index(i, j, k)] = label(i - cx, j - cy, k - cz);
  return v;
}

/// A cube of n^3 voxels (spacing 1 mm) labelled by `label` at centred coordinates.
inline LabelVolume makeVolume(int n, const std::function<int32_t(double, double, double)>& label) {
  return makeVolume({n, n, n}, {1, 1, 1}, label);
}

/// `v` with the materials "m<id>" (default colours) for the given labels.
inline LabelVolume withMaterials(LabelVolume v, std::initializer_list<int32_t> ids) {
  for (int32_t id : ids)
    v.materials.push_back({id, "m" + std::to_string(id), defaultLabelColor(id)});
  return v;
}

/// Label of ballsInShell(n) at centred coordinates.
inline int32_t ballsInShellLabel(int n, double x, double y, double z) {
  const double r = std::sqrt(x * x + y * y + z * z);
  int32_t l = 0;
  if (r < 0.45 * n) l = 3;
  if (r < 0.36 * n) l = x < 0 ? 1 : 2;
  return l;
}

/// n^3 voxels, 1 mm: two half balls 1 (x < 0) and 2 (x >= 0) touching on the plane x = 0, radius
/// 0.36 n, inside a shell 3 (outer radius 0.45 n), background 0 around; materials m1..m3. The
/// balls and the shell meet on a triple line (a circle); the balls are enclosed by the shell.
inline LabelVolume ballsInShell(int n = 40) {
  return withMaterials(
      makeVolume(n, [n](double x, double y, double z) { return ballsInShellLabel(n, x, y, z); }),
      {1, 2, 3});
}

/// ballsInShell(n) without background: label 4 fills the rest of the box, so every voxel is
/// labelled and material 4 is cut by the volume's box (the box is the outer boundary);
/// materials m1..m4.
inline LabelVolume ballsInShellWithoutBackground(int n) {
  LabelVolume v = ballsInShell(n);
  for (auto& l : v.labels)
    if (l == 0) l = 4;
  return withMaterials(v, {4});
}

/// ballsInShell(n) plus two cavities of radius 0.1 n: an empty (background) pocket inside ball 1
/// and a small ball of label 4 inside ball 2, i.e. regions enclosed by another material;
/// materials m1..m4.
inline LabelVolume ballsWithCavities(int n = 40) {
  const LabelVolume v = makeVolume(n, [n](double x, double y, double z) {
    int32_t l = ballsInShellLabel(n, x, y, z);
    if ((x + 0.18 * n) * (x + 0.18 * n) + y * y + z * z < 0.01 * n * n) l = 0;
    if ((x - 0.18 * n) * (x - 0.18 * n) + y * y + z * z < 0.01 * n * n) l = 4;
    return l;
  });
  return withMaterials(v, {1, 2, 3, 4});
}

/// 36^3 voxels, 1 mm: ball 1 (radius 8, centre x = -7) and ball 2 (radius 8, centre x = +7, only
/// x >= 0) touching in a thin lens near x = 0; a triple line (1, 2 and background) runs round it.
inline LabelVolume twoSpheres() {
  return makeVolume(36, [](double x, double y, double z) {
    if ((x + 7) * (x + 7) + y * y + z * z < 64) return 1;
    if ((x - 7) * (x - 7) + y * y + z * z < 64 && x >= 0) return 2;
    return 0;
  });
}

/// 36^3 voxels, 1 mm: a ball of radius 15 cut into three wedges 1, 2, 3 (by the angle about the
/// z axis at -1.0 and 1.2 rad and at pi), which meet on one triple line, the z axis (centred
/// coordinates); each pair of wedges also meets the background on the ball's surface.
inline LabelVolume threeSlabs() {
  return makeVolume(36, [](double x, double y, double z) {
    if (x * x + y * y + z * z >= 15 * 15) return 0;
    const double a = std::atan2(y, x);
    return a < -1.0 ? 1 : (a < 1.2 ? 2 : 3);
  });
}

/// 36^3 voxels, 1 mm: a ball of radius 15 split by the plane z = 0.3 into 1 (x < 0.2) and 2
/// below, and 3 (y < -0.4) and 4 above (centred coordinates): the four materials meet at one
/// quadruple point, near (0.2, -0.4, 0.3), with four triple lines leaving it.
inline LabelVolume fourAtAPoint() {
  return makeVolume(36, [](double x, double y, double z) {
    if (x * x + y * y + z * z >= 15 * 15) return 0;
    if (z < 0.3) return x < 0.2 ? 1 : 2;
    return y < -0.4 ? 3 : 4;
  });
}

/// n^3 voxels, 1 mm: a square plate 1 one voxel thick (the layer k = n / 2, i and j in
/// [n / 4, n - n / 4)) in background: thinner than any smoothing or sampling scale.
inline LabelVolume oneVoxelPlate(int n = 24) {
  LabelVolume v = makeVolume(n, [](double, double, double) { return 0; });
  for (int j = n / 4; j < n - n / 4; ++j)
    for (int i = n / 4; i < n - n / 4; ++i) v.labels[v.index(i, j, n / 2)] = 1;
  return v;
}

/// n^3 voxels (n even), 1 mm: a straight rod 1 of 2 x 2 voxels cross-section along the x axis
/// (|x| < 0.4 n), in background.
inline LabelVolume thinRod(int n = 32) {
  return makeVolume(n, [n](double x, double y, double z) {
    return y * y + z * z < 1.0 && std::fabs(x) < 0.4 * n ? 1 : 0;
  });
}

/// n^3 voxels, 1 mm: a core ball 1 (radius 0.2 n) inside two nested, touching spherical shells
/// 2 (to radius 0.28 n) and 3 (to radius 0.36 n), in background. Each shell is a few voxels thick
/// (2.5 for n = 32); every interface is a closed sphere and no three materials meet (for n = 24
/// no dual cell of 2 x 2 x 2 voxels holds three labels: Junctions.NoneWhereOnlyTwoMaterialsMeet).
inline LabelVolume nestedThinShells(int n = 32) {
  return makeVolume(n, [n](double x, double y, double z) {
    const double r = std::sqrt(x * x + y * y + z * z);
    return r < 0.2 * n ? 1 : r < 0.28 * n ? 2 : r < 0.36 * n ? 3 : 0;
  });
}

/// n^3 voxels, spacing 1 x 1 x 1.5 mm: a ball 1 (radius 0.42 n voxels) cut by a one-voxel plate 2
/// (the layer i = int(centre) + 2), with a thin oblique rod 3 (axis along (1, 1, 0.5), radius
/// 1.2 voxels) through it: thin, staircased features where a coarse piecewise-linear surface
/// misses voxel centres.
inline LabelVolume thinFeatures(int n = 36) {
  const double c = (n - 1) / 2.0;
  return makeVolume({n, n, n}, {1.0, 1.0, 1.5}, [n, c](double x, double y, double z) {
    int32_t l = 0;
    if (x * x + y * y + z * z < 0.42 * 0.42 * n * n) l = 1;
    if (l == 1 && std::lround(x + c) == int(c) + 2) l = 2;
    // Rod along (1, 1, 0.5): distance from the axis below 1.2 voxels.
    const double t = (x + y + 0.5 * z) / 1.5;
    const double dx = x - t * (1 / 1.5), dy = y - t * (1 / 1.5), dz = z - t * (0.5 / 1.5);
    if (dx * dx + dy * dy + dz * dz < 1.44 && std::fabs(t) < 0.4 * n) l = 3;
    return l;
  });
}

/// n^3 voxels (n even), 1 mm: a cube 2 of (2 inner)^3 voxels inside a cube 1 of (2 outer)^3
/// voxels, both centred, in background: two materials with flat faces on voxel boundaries, sharp
/// edges and corners; material 1 encloses 2 as a cavity.
inline LabelVolume cubeInCube(int n, int outer, int inner) {
  return makeVolume(n, [outer, inner](double x, double y, double z) {
    const double m = std::max({std::fabs(x), std::fabs(y), std::fabs(z)});
    return m < inner ? 2 : m < outer ? 1 : 0;
  });
}

/// `v` (labels kept) placed with an oblique, left-handed, anisotropic geometry: `spacing`,
/// `origin` (LPS mm) and direction Rz(yaw) * Rx(tilt) * diag(mirror), i.e. a rotation about a
/// skew axis composed with the reflection `mirror` (each entry +1 or -1; left-handed when their
/// product is -1). The defaults: spacing 0.7 x 1.1 x 1.6 mm (x smallest), origin (10, -20, 5),
/// yaw 0.4 rad, tilt 0.3 rad, z mirrored (det = -1).
inline LabelVolume obliqueLeftHanded(LabelVolume v, const Vec3& spacing = {0.7, 1.1, 1.6},
                                     const Vec3& origin = {10, -20, 5}, double yaw = 0.4,
                                     double tilt = 0.3, const Vec3& mirror = {1, 1, -1}) {
  v.spacing = spacing;
  v.origin = origin;
  const double a = yaw, b = tilt;
  const double R[9] = {std::cos(a),
                       -std::sin(a) * std::cos(b),
                       std::sin(a) * std::sin(b),
                       std::sin(a),
                       std::cos(a) * std::cos(b),
                       -std::cos(a) * std::sin(b),
                       0,
                       std::sin(b),
                       std::cos(b)};
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) v.direction[size_t(3 * r + c)] = R[3 * r + c] * mirror[size_t(c)];
  return v;
}

/// `input` after stages 1 and 2 (default preprocessing; indicator functions with `sigma` voxels
/// and a band of 4 voxels): what the later stages start from. The volume is held by pointer, so
/// the field's reference to it survives moving the struct.
struct IndicatorInputs {
  LabelVolume input;
  std::unique_ptr<PreprocessedVolume> vol;
  std::unique_ptr<IndicatorField> field;
};

inline IndicatorInputs computeIndicatorInputs(const LabelVolume& input, double sigma) {
  IndicatorInputs in;
  in.input = input;
  RunContext ctx;
  in.vol = std::make_unique<PreprocessedVolume>(preprocessLabels(input, {}, ctx));
  IndicatorParameters ip;
  ip.sigma = sigma;
  ip.band = 4;
  in.field = std::make_unique<IndicatorField>(computeIndicatorFunctions(*in.vol, ip, ctx));
  return in;
}

}  // namespace femesher::test
