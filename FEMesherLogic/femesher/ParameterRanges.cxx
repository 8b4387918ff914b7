// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/ParameterRanges.h>
#include <femesher/stages/SizingField.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

namespace femesher {

namespace {

const double kRegularTet = 1.0 / (6.0 * std::sqrt(2.0));  // volume of a regular tet of edge 1

std::string num(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.3g", v);
  return b;
}

/// "about 6.6e+11 tets" / "about 120 M tets" / "about 3400 tets".
std::string tets(double n) {
  if (n >= 1e9 || !std::isfinite(n)) return "about " + num(n) + " tets";
  if (n >= 1e6) return "about " + num(n / 1e6) + " M tets";
  return "about " + num(n) + " tets";
}

std::string ofFile(const LabelVolume& v) {
  return v.sourcePath.empty() ? std::string("this label map") : "'" + v.sourcePath + "'";
}

std::string ceilingText() { return num(kMaxEstimatedTets / 1e6) + " M tets"; }

/// The largest of the floor and the count bound for an edge length on `e`.
double smallestEdge(const VolumeExtent& e) {
  const double byCount = std::cbrt(e.meshedVolume / (kRegularTet * kMaxEstimatedTets));
  return std::max(kLengthFloorVoxels * e.smallestSpacing, byCount);
}

/// Why `h` (mm) is refused, or "" when it is within range.
std::string edgeProblem(double h, const VolumeExtent& e) {
  const double floor = kLengthFloorVoxels * e.smallestSpacing;
  const double n = estimatedTets(e.meshedVolume, h);
  if (n > kMaxEstimatedTets)
    return "it would make " + tets(n) + " (" + num(e.meshedVolume) + " mm^3 of materials / " +
           num(kRegularTet * h * h * h) + " mm^3 per tet of that edge length; the ceiling is " +
           ceilingText() + ")";
  if (h < floor)
    return "it is below " + num(kLengthFloorVoxels) + " x the smallest voxel spacing (" +
           num(e.smallestSpacing) + " mm): the label map holds no detail that small";
  return {};
}

Status refuse(const std::string& text) { return {ErrorCode::InvalidArgument, text}; }

}  // namespace

VolumeExtent volumeExtent(const LabelVolume& volume) {
  VolumeExtent e;
  const auto& s = volume.spacing;
  e.smallestSpacing = std::min({s[0], s[1], s[2]});
  e.meanSpacing = (s[0] + s[1] + s[2]) / 3.0;
  size_t material = 0;
  for (int32_t l : volume.labels) material += l != 0;
  if (volume.hasNoBackground()) material = volume.labels.size();
  e.meshedVolume = double(material) * s[0] * s[1] * s[2];
  return e;
}

double estimatedTets(double meshedVolume, double h) {
  return h > 0 ? meshedVolume / (kRegularTet * h * h * h) : HUGE_VAL;
}

Status checkSizeParameters(const MeshingParameters& p, const LabelVolume& volume) {
  const VolumeExtent e = volumeExtent(volume);
  if (!(e.meshedVolume > 0) || volume.labels.empty()) return Status::ok();  // empty: said later
  const std::string file = ofFile(volume);
  const double hLow = smallestEdge(e);
  const std::string range = "; the smallest useful value for " + file + " is " + num(hLow) +
                            " mm (at most " + ceilingText() + ", and at least " +
                            num(kLengthFloorVoxels) + " x the smallest voxel spacing)";
  const SizingParameters& sz = p.sizing;
  if (sz.targetEdgeLength > 0) {
    if (std::string why = edgeProblem(sz.targetEdgeLength, e); !why.empty())
      return refuse("target_edge_length = " + num(sz.targetEdgeLength) + " mm is too small for " +
                    file + ": " + why + range + ". Use a value >= " + num(hLow) +
                    " mm, or 0 for the automatic size.");
  } else {
    // The automatic size: edge_length_factor x the mean spacing (at most a quarter of the extent).
    const double h = uniformEdgeLength(volume, sz);
    if (std::string why = edgeProblem(h, e); !why.empty())
      return refuse("edge_length_factor = " + num(sz.edgeLengthFactor) + " gives an edge length of " +
                    num(h) + " mm on " + file + ", too small: " + why + range +
                    ". Use edge_length_factor >= " + num(sz.edgeLengthFactor * hLow / h) +
                    ", or set target_edge_length >= " + num(hLow) + " mm.");
  }
  if (sz.hMax > 0)
    if (std::string why = edgeProblem(sz.hMax, e); !why.empty())
      return refuse("h_max = " + num(sz.hMax) + " mm is too small for " + file +
                    ": no edge may be longer, so " + why + range + ". Use h_max >= " + num(hLow) +
                    " mm, or 0 for automatic.");
  const double floor = kLengthFloorVoxels * e.smallestSpacing;
  if (sz.hMin > 0 && sz.hMin < floor)
    return refuse("h_min = " + num(sz.hMin) + " mm is too small for " + file + ": it is below " +
                  num(kLengthFloorVoxels) + " x the smallest voxel spacing (" +
                  num(e.smallestSpacing) + " mm), detail the label map does not hold. Use h_min >= " +
                  num(floor) + " mm, or 0 for automatic.");
  const double vMax = p.volume.maxTetVolume;
  if (vMax > 0) {
    const double vLow = std::max(e.meshedVolume / kMaxEstimatedTets, kRegularTet * floor * floor * floor);
    if (vMax < vLow) {
      const double n = e.meshedVolume / vMax;
      const std::string why =
          n > kMaxEstimatedTets
              ? "every tet at most that large makes at least " + tets(n) + " (" +
                    num(e.meshedVolume) + " mm^3 of materials; the ceiling is " + ceilingText() + ")"
              : "it is below the volume of a tet of edge " + num(kLengthFloorVoxels) +
                    " x the smallest voxel spacing (" + num(e.smallestSpacing) + " mm)";
      return refuse("max_tet_volume = " + num(vMax) + " mm^3 is too small for " + file + ": " + why +
                    "; the smallest useful value for " + file + " is " + num(vLow) +
                    " mm^3. Use max_tet_volume >= " + num(vLow) + " mm^3, or 0 for no bound.");
    }
  }
  const double fd = p.boundary.facetDistance;
  if (fd > 0 && fd < kFacetDistanceFloorVoxels)
    return refuse("facet_distance = " + num(fd) + " voxels is too small for " + file +
                  ": surface refinement would insert points until every interface triangle is "
                  "within " + num(fd * e.smallestSpacing) + " mm of the smooth interface, far "
                  "below the label map's resolution. Use facet_distance >= " +
                  num(kFacetDistanceFloorVoxels) + " voxels, or 0 for no refinement.");
  return Status::ok();
}

}  // namespace femesher
