// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/HipPhantom.h>
#include <femesher/Parallel.h>
#include <femesher/Status.h>
#include <femesher/VecMath.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <sstream>
#include <utility>
#include <vector>
#include <string>

namespace femesher {

namespace {

// All lengths in mm, in the volume's frame: x from the patient's right to left, y from anterior
// to posterior, z from the distal thigh (0) to above the iliac crest (400).
constexpr double kExtentXY = 0.7 * 512, kExtentZ = 1.0 * 400;
constexpr double kX0 = kExtentXY / 2, kY0 = kExtentXY / 2;
constexpr double kHeadRadius = 23;      // native femoral head
constexpr double kCartilage = 3;        // cartilage between head and acetabulum
constexpr double kSocketRadius = kHeadRadius + kCartilage;  // acetabulum (both sides)
constexpr double kBallRadius = 16;      // prosthetic head; the cup fills ball .. socket
constexpr double kPelvisCortex = 2;
constexpr double kFatLayer = 14;
constexpr double kCovered = -0.15;      // cartilage where (p - H)/|p - H| . axis > kCovered
constexpr double kPlateMargin = 0.1;    // the subchondral plate's region reaches a bit further

double smin(double a, double b, double k) {
  const double h = std::max(k - std::abs(a - b), 0.0) / k;
  return std::min(a, b) - h * h * k * 0.25;
}

double clamp01(double t) { return std::min(1.0, std::max(0.0, t)); }

double smoothstep(double e0, double e1, double x) {
  const double t = clamp01((x - e0) / (e1 - e0));
  return t * t * (3 - 2 * t);
}

Vec3 normalized(const Vec3& a) { return scale(a, 1.0 / norm(a)); }

/// A bound of the signed distance to an ellipsoid with radii r, in its own axes (q local).
double ellipsoidLocal(const Vec3& q, const Vec3& r) {
  const double k0 = std::sqrt(std::pow(q[0] / r[0], 2) + std::pow(q[1] / r[1], 2) + std::pow(q[2] / r[2], 2));
  const double k1 = std::sqrt(std::pow(q[0] / (r[0] * r[0]), 2) + std::pow(q[1] / (r[1] * r[1]), 2) +
                              std::pow(q[2] / (r[2] * r[2]), 2));
  return k1 > 0 ? k0 * (k0 - 1) / k1 : -std::min({r[0], r[1], r[2]});
}

double ellipsoid(const Vec3& p, const Vec3& c, const Vec3& r) { return ellipsoidLocal(sub(p, c), r); }

/// A segment from a (radius ra) to b (radius rb), radius interpolated along it.
double taperedCapsule(const Vec3& p, const Vec3& a, const Vec3& b, double ra, double rb) {
  const Vec3 ab = sub(b, a);
  const double t = clamp01(dot(sub(p, a), ab) / dot(ab, ab));
  return norm(sub(p, add(a, scale(ab, t)))) - (ra + t * (rb - ra));
}

double capsule(const Vec3& p, const Vec3& a, const Vec3& b, double r) {
  return taperedCapsule(p, a, b, r, r);
}

/// One side's femur and acetabulum; s = +1 the patient's left (native), -1 the right (implant).
struct Side {
  double s = 1;
  Vec3 head, neckEnd, trochanter, lesser, shaftTop, shaftBottom;
  Vec3 axis;            // acetabular axis: from the head centre into the pelvis
  Vec3 cutPoint, cutNormal;  // the neck osteotomy (implant side): bone where (p - cut).n < 0
  Vec3 stemTop, stemTip;
  // Pelvis parts
  Vec3 acetabulum, iliumCentre, iliumU, iliumV, iliumW, iliacBody, sacroiliacA, sacroiliacB,
      ramusA, ramusB, pubis, ischiumA, tuberosity, inferiorRamusEnd;

  explicit Side(double side) : s(side) {
    head = {kX0 + s * 88, kY0 - 5, 262};
    neckEnd = {kX0 + s * 122, kY0, 228};
    trochanter = {kX0 + s * 130, kY0 + 6, 232};
    lesser = {kX0 + s * 108, kY0 + 12, 200};
    shaftTop = {kX0 + s * 122, kY0, 235};
    shaftBottom = {kX0 + s * 100, kY0 - 5, -20};
    axis = normalized({-s * 0.64, 0.25, 0.72});
    cutPoint = add(head, scale(sub(neckEnd, head), 0.45));
    cutNormal = normalized(sub(head, neckEnd));
    stemTop = shaftAxisAt(215);
    stemTip = shaftAxisAt(105);
    acetabulum = add(head, {-s * 8, 4, 10});
    iliumCentre = {kX0 + s * 84, kY0 + 16, 318};
    iliumU = normalized({s * 0.8, -0.5, -0.3});
    iliumW = normalized(sub({0, 0, 1}, scale(iliumU, iliumU[2])));
    iliumV = cross(iliumW, iliumU);
    iliacBody = {kX0 + s * 86, kY0 + 14, 292};
    sacroiliacA = {kX0 + s * 38, kY0 + 60, 322};
    sacroiliacB = {kX0 + s * 72, kY0 + 36, 320};
    ramusA = add(acetabulum, {-s * 14, -18, -6});
    ramusB = {kX0 + s * 12, kY0 - 58, 228};
    pubis = {kX0 + s * 13, kY0 - 58, 220};
    ischiumA = add(acetabulum, {0, 14, -16});
    tuberosity = {kX0 + s * 56, kY0 + 22, 192};
    inferiorRamusEnd = {kX0 + s * 15, kY0 - 52, 206};
  }

  Vec3 shaftAxisAt(double z) const {
    const double t = (shaftTop[2] - z) / (shaftTop[2] - shaftBottom[2]);
    return add(shaftTop, scale(sub(shaftBottom, shaftTop), t));
  }
  bool implant() const { return s < 0; }
  bool nearFemur(const Vec3& p) const {
    return std::abs(p[0] - (kX0 + s * 110)) < 60 && std::abs(p[1] - kY0) < 50 && p[2] < 300;
  }

  /// Signed distance (bound) to the femur, cut at the neck on the implant side.
  double femur(const Vec3& p) const {
    double d = norm(sub(p, head)) - kHeadRadius;
    d = smin(d, capsule(p, head, neckEnd, 14), 8);
    d = smin(d, capsule(p, shaftTop, shaftBottom, 13), 10);
    d = smin(d, ellipsoid(p, trochanter, {14, 18, 24}), 8);
    d = smin(d, norm(sub(p, lesser)) - 9, 6);
    if (implant()) d = std::max(d, dot(sub(p, cutPoint), cutNormal));
    return d;
  }
  /// Cortex thickness: 6 mm on the shaft, 2 mm at the metaphysis, neck and trochanters.
  static double cortex(double z) { return 2.0 + 4.0 * smoothstep(185, 145, z); }
  bool marrow(const Vec3& p) const { return capsule(p, shaftAxisAt(165), shaftBottom, 8) < 0; }
  /// Cosine between p - head and the acetabular axis (1 at the centre).
  double cover(const Vec3& p) const {
    const Vec3 d = sub(p, head);
    const double r = norm(d);
    return r > 0 ? dot(d, axis) / r : 1.0;
  }
  bool prosthesis(const Vec3& p) const {
    const double r = norm(sub(p, head));
    if (r < kBallRadius) return true;
    if (r < kSocketRadius && dot(sub(p, head), axis) >= 0) return true;  // the cup
    if (capsule(p, stemTop, head, 6.5) < 0) return true;                 // the neck
    // The stem fills the canal (radius 7 below z = 145 mm, wider above): marrow only below it.
    return taperedCapsule(p, stemTop, stemTip, 9.5, 7.2) < 0;
  }
  double pelvisPart(const Vec3& p) const {
    const Vec3 q = sub(p, iliumCentre);
    double d = ellipsoidLocal({dot(q, iliumU), dot(q, iliumV), dot(q, iliumW)}, {10, 44, 58});
    d = smin(d, ellipsoid(p, acetabulum, {30, 30, 32}), 8);
    d = smin(d, capsule(p, acetabulum, iliacBody, 20), 8);
    d = smin(d, capsule(p, sacroiliacA, sacroiliacB, 15), 8);
    d = smin(d, capsule(p, ramusA, ramusB, 9), 8);
    d = smin(d, ellipsoid(p, pubis, {12, 10, 18}), 8);
    d = smin(d, capsule(p, ischiumA, tuberosity, 13), 8);
    d = smin(d, capsule(p, tuberosity, inferiorRamusEnd, 8), 8);
    return d;
  }
};

struct Hip {
  Side left{1}, right{-1};
  Vec3 h;  // voxel spacing, for the subchondral plate's 26-neighbour test
  /// Thin cortices are at least 1.3 voxels thick (along the coarsest axis), so that coarse
  /// scales keep trabecular bone enclosed.
  double minCortex = 0;

  double body(const Vec3& p) const {
    const double ex = (p[0] - kX0) / 155, ey = (p[1] - kY0 - 8) / 112;
    const double k0 = std::hypot(ex, ey), k1 = std::hypot(ex / 155, ey / 112);
    const double trunk = std::max(k1 > 0 ? k0 * (k0 - 1) / k1 : -112, 175 - p[2]);
    const double r = 62 + 16 * clamp01(p[2] / 250);
    double thighs = 1e9;
    for (double s : {-1.0, 1.0})
      thighs = std::min(thighs, std::max(std::hypot(p[0] - kX0 - s * 82, p[1] - kY0) - r, p[2] - 280));
    return smin(trunk, thighs, 40);
  }

  bool nearPelvis(const Vec3& p) const {
    return std::abs(p[0] - kX0) < 145 && p[1] > kY0 - 85 && p[1] < kY0 + 95 && p[2] > 160 && p[2] < 392;
  }

  double pelvis(const Vec3& p) const {
    double d = ellipsoid(p, {kX0, kY0 + 62, 318}, {40, 20, 56});  // sacrum
    d = smin(d, left.pelvisPart(p), 8);
    d = smin(d, right.pelvisPart(p), 8);
    for (const Side* side : {&left, &right}) {
      d = std::max(d, kSocketRadius - norm(sub(p, side->head)));
      if (d < 0 && side->nearFemur(p)) d = std::max(d, 3 - side->femur(p));  // 3 mm clearance
    }
    return d;
  }

  int32_t femurLabel(const Side& side, const Vec3& p, double d) const {
    if (!side.implant() && norm(sub(p, side.head)) < kSocketRadius + 1 &&
        side.cover(p) > kCovered - kPlateMargin) {
      // Under the cartilage: the subchondral plate (voxels whose farthest 26-neighbour from the
      // head centre is outside the femur), trabecular bone beneath.
      Vec3 corner = p;
      for (int a = 0; a < 3; ++a) corner[a] += p[a] >= side.head[a] ? h[a] : -h[a];
      return side.femur(corner) >= 0 ? kHipSubchondralPlate : kHipFemurTrabecular;
    }
    if (d > -std::max(minCortex, Side::cortex(p[2]))) return kHipFemurCortical;
    return side.marrow(p) ? kHipMarrow : kHipFemurTrabecular;
  }

  int32_t label(const Vec3& p) const {
    const double b = body(p);
    if (b >= 0) return 0;
    for (const Side* side : {&right, &left}) {
      if (!side->nearFemur(p) && !(side->implant() && norm(sub(p, side->head)) < kSocketRadius))
        continue;
      if (side->implant() && side->prosthesis(p)) return kHipImplant;
      if (!side->nearFemur(p)) continue;
      const double d = side->femur(p);
      if (d < 0) return femurLabel(*side, p, d);
      if (!side->implant() && norm(sub(p, side->head)) < kSocketRadius && side->cover(p) > kCovered)
        return kHipCartilage;
    }
    if (nearPelvis(p)) {
      const double d = pelvis(p);
      if (d < 0)
        return d > -std::max(minCortex, kPelvisCortex) ? kHipPelvisCortical : kHipPelvisTrabecular;
    }
    return b > -kFatLayer ? kHipFat : kHipMuscle;
  }
};

/// Gives every 6-connected component smaller than `fraction` of its label's largest component
/// the most common label among its 6-neighbours outside it: the one-voxel slivers where the
/// analytic shapes cut each other at a voxel's scale.
void removeSlivers(LabelVolume& v, double fraction) {
  const size_t n = v.voxelCount();
  const int nx = v.dims[0], ny = v.dims[1], nz = v.dims[2];
  const size_t sx = 1, sy = size_t(nx), sz = size_t(nx) * size_t(ny);
  std::vector<uint8_t> seen(n, 0);
  std::vector<size_t> stack, members;
  struct Component { int32_t label; size_t seed, size; };
  std::vector<Component> components;
  std::map<int32_t, size_t> largest;
  // Visits the component of `seed` (voxels not yet marked `mark`), calling visit(index).
  auto walk = [&](size_t seed, uint8_t mark, auto&& visit) {
    const int32_t label = v.labels[seed];
    stack.assign(1, seed);
    seen[seed] = mark;
    while (!stack.empty()) {
      const size_t q = stack.back();
      stack.pop_back();
      visit(q);
      const int i = int(q % sy), j = int((q / sy) % size_t(ny)), k = int(q / sz);
      const std::pair<bool, size_t> next[6] = {{i > 0, q - sx}, {i + 1 < nx, q + sx}, {j > 0, q - sy},
                                               {j + 1 < ny, q + sy}, {k > 0, q - sz}, {k + 1 < nz, q + sz}};
      for (const auto& [ok, r] : next)
        if (ok && seen[r] != mark && v.labels[r] == label) {
          seen[r] = mark;
          stack.push_back(r);
        }
    }
  };
  for (size_t q = 0; q < n; ++q) {
    if (seen[q]) continue;
    size_t size = 0;
    walk(q, 1, [&](size_t) { ++size; });
    components.push_back({v.labels[q], q, size});
    largest[v.labels[q]] = std::max(largest[v.labels[q]], size);
  }
  for (const Component& c : components) {
    if (double(c.size) >= fraction * double(largest[c.label])) continue;
    members.clear();
    walk(c.seed, 2, [&](size_t q) { members.push_back(q); });
    std::map<int32_t, size_t> around;
    for (size_t q : members) {
      const int i = int(q % sy), j = int((q / sy) % size_t(ny)), k = int(q / sz);
      const std::pair<bool, size_t> next[6] = {{i > 0, q - sx}, {i + 1 < nx, q + sx}, {j > 0, q - sy},
                                               {j + 1 < ny, q + sy}, {k > 0, q - sz}, {k + 1 < nz, q + sz}};
      for (const auto& [ok, r] : next)
        if (ok && v.labels[r] != c.label) ++around[v.labels[r]];
    }
    if (around.empty()) continue;
    const int32_t to = std::max_element(around.begin(), around.end(), [](const auto& a, const auto& b) {
                         return a.second < b.second;
                       })->first;
    for (size_t q : members) v.labels[q] = to;
  }
}

}  // namespace

LabelVolume hipPhantomHeader(const HipPhantomOptions& o) {
  if (!(o.scale > 0.05 && o.scale <= 2)) {
    std::ostringstream m;
    m << "hip phantom scale " << o.scale << ": use a value in (0.05, 2] (1: 512 x 512 x 400 voxels)";
    throw Error(ErrorCode::InvalidArgument, m.str());
  }
  LabelVolume v;
  const int nxy = int(std::lround(512 * o.scale)), nz = int(std::lround(400 * o.scale));
  v.dims = {nxy, nxy, nz};
  v.spacing = {0.7 * 512 / nxy, 0.7 * 512 / nxy, 1.0 * 400 / nz};
  // Centred left-right and front-back, the top of the field of view 40 mm above the iliac crest.
  v.origin = {-kX0 + v.spacing[0] / 2, -kY0 + v.spacing[1] / 2, -kExtentZ + 40 + v.spacing[2] / 2};
  v.sourcePath = "hip phantom";
  return v;
}

LabelVolume makeHipPhantom(const HipPhantomOptions& o) {
  LabelVolume v = hipPhantomHeader(o);
  const int nxy = v.dims[0], nz = v.dims[2];
  v.labels.assign(v.voxelCount(), 0);
  Hip hip;
  hip.h = v.spacing;
  hip.minCortex = 1.3 * std::max({v.spacing[0], v.spacing[1], v.spacing[2]});
  const size_t slice = size_t(nxy) * size_t(nxy);
  // One chunk per z slice: each voxel is computed from its own position only, so the labels do
  // not depend on the thread count.
  parallelFor(size_t(nz), o.threads, [&](size_t k0, size_t k1, int) {
    for (size_t k = k0; k < k1; ++k)
      for (int j = 0; j < nxy; ++j)
        for (int i = 0; i < nxy; ++i) {
          const Vec3 p{(i + 0.5) * v.spacing[0], (j + 0.5) * v.spacing[1], (double(k) + 0.5) * v.spacing[2]};
          v.labels[k * slice + size_t(j) * size_t(nxy) + size_t(i)] = hip.label(p);
        }
  }, nz);
  removeSlivers(v, 0.02);
  v.materials = {{kHipPelvisCortical, "pelvis cortical bone", {0.96, 0.93, 0.82}},
                 {kHipPelvisTrabecular, "pelvis trabecular bone", {0.86, 0.66, 0.44}},
                 {kHipFemurCortical, "femur cortical bone", {0.92, 0.88, 0.70}},
                 {kHipFemurTrabecular, "femur trabecular bone", {0.80, 0.56, 0.36}},
                 {kHipMarrow, "marrow", {0.78, 0.25, 0.25}},
                 {kHipCartilage, "cartilage", {0.35, 0.65, 0.92}},
                 {kHipImplant, "implant", {0.55, 0.50, 0.88}},
                 {kHipMuscle, "muscle", {0.75, 0.35, 0.35}},
                 {kHipFat, "fat", {0.95, 0.85, 0.55}},
                 {kHipSubchondralPlate, "subchondral bone plate", {1.00, 1.00, 0.95}}};
  return v;
}

}  // namespace femesher
