// SPDX-License-Identifier: GPL-3.0-or-later
#include "Inspect.h"

#include "CliCommon.h"

#include <femesher/Parameters.h>
#include <femesher/HipPhantom.h>
#include <femesher/Phantom.h>
#include <femesher/Pipeline.h>
#include <femesher/io/LabelMapIO.h>
#include <femesher/io/MeshIO.h>
#include <femesher/stages/Fidelity.h>
#include <femesher/stages/MedialAxis.h>
#include <femesher/stages/Quality.h>

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cstdio>
#include <optional>
#include <sstream>

namespace femesher::cli {

int runInfo(const std::string& input, const std::string& labelNames, bool asJson) {
  auto volume = readNamedLabelMap(input, labelNames);
  if (!volume) return fail(volume.status());
  const LabelVolume& v = volume.value();
  const LabelMapSummary s = summarizeLabelMap(v);
  if (asJson) {
    std::ostringstream os;
    os << "{\n  \"path\": \"" << input << "\",\n  \"dims\": [" << v.dims[0] << ", " << v.dims[1]
       << ", " << v.dims[2] << "],\n  \"spacing\": [" << v.spacing[0] << ", " << v.spacing[1]
       << ", " << v.spacing[2] << "],\n  \"origin\": [" << v.origin[0] << ", " << v.origin[1]
       << ", " << v.origin[2] << "],\n  \"direction\": [";
    for (int i = 0; i < 9; ++i) os << v.direction[i] << (i < 8 ? ", " : "");
    os << "],\n  \"labels\": [";
    for (size_t i = 0; i < s.labels.size(); ++i) {
      const auto& l = s.labels[i];
      os << (i ? ",\n" : "\n") << "    {\"id\": " << l.id << ", \"name\": \"" << jsonText(l.name)
         << "\", \"voxels\": " << l.voxels << ", \"volume_mm3\": " << l.volumeMm3
         << ", \"components\": " << l.components << "}";
    }
    os << "\n  ],\n  \"touching_pairs\": " << s.touchingPairs.size()
       << ",\n  \"triple_cells\": " << s.tripleCells << ",\n  \"quadruple_cells\": "
       << s.quadrupleCells << "\n}\n";
    std::fputs(os.str().c_str(), stdout);
    return 0;
  }
  std::printf("%s\n", input.c_str());
  std::printf("  dims      %d x %d x %d\n", v.dims[0], v.dims[1], v.dims[2]);
  std::printf("  spacing   %g x %g x %g mm\n", v.spacing[0], v.spacing[1], v.spacing[2]);
  std::printf("  origin    (%g, %g, %g) LPS\n", v.origin[0], v.origin[1], v.origin[2]);
  std::printf("  direction [%g %g %g; %g %g %g; %g %g %g]%s\n", v.direction[0], v.direction[1],
              v.direction[2], v.direction[3], v.direction[4], v.direction[5], v.direction[6],
              v.direction[7], v.direction[8],
              v.directionDeterminant() < 0 ? " (left-handed)" : "");
  std::printf("  %-8s %-28s %12s %14s %10s\n", "label", "name", "voxels", "volume mm^3", "components");
  for (const auto& l : s.labels)
    std::printf("  %-8d %-28s %12zu %14.1f %10d\n", l.id, l.name.c_str(), l.voxels, l.volumeMm3,
                l.components);
  std::printf("  touching label pairs: %zu; 2x2x2 cells with >=3 labels: %zu, >=4 labels: %zu\n",
              s.touchingPairs.size(), s.tripleCells, s.quadrupleCells);
  return 0;
}

int runQuality(const std::string& meshPath, const std::string& labelsPath,
               const std::string& rasterPath, bool asJson) {
  if (!rasterPath.empty() && labelsPath.empty())
    return fail(Status(ErrorCode::InvalidArgument,
                       "--raster needs --labels: the mesh is sampled on that label map's voxel grid"));
  CancellableCommand command;
  std::optional<ReadingScope> computing(std::in_place);  // nothing written until the raster
  auto file = readMeshFile(meshPath);
  if (!file) return fail(file.status());
  const TetMesh* mesh = &file->mesh;  // the corner tets of a 10-node mesh
  // 10-node tets: the Jacobian of the quadratic map at the 11 check points of every element.
  Tet10Jacobian worst;
  size_t folded = 0;
  if (file->elementOrder == 2) {
    const QuadraticTetMesh q = quadraticTets(*mesh, &file->midEdgeNodes);
    std::array<Vec3, 10> x;
    for (const auto& t : q.tets) {
      for (size_t k = 0; k < 10; ++k) x[k] = q.points[size_t(t[k])];
      const Tet10Jacobian j = tet10Jacobian(x);
      folded += j.minOverStraight <= 0;
      worst.minOverStraight = std::min(worst.minOverStraight, j.minOverStraight);
      worst.minOverMax = std::min(worst.minOverMax, j.minOverMax);
    }
  }
  RunContext& ctx = command.ctx;
  const QualityReport q = computeQuality(*mesh, ctx);
  FidelityReport fr;
  const bool withFidelity = !labelsPath.empty();
  if (withFidelity) {
    auto labels = readLabelMap(labelsPath);
    if (!labels) return fail(labels.status());
    fr = computeFidelity(labels.value(), *mesh, ctx);
    if (!rasterPath.empty()) {
      const LabelVolume raster = rasterizeMesh(labels.value(), *mesh);
      computing.reset();  // a signal from here on stops the write before its rename
      if (Status st = writeLabelMap(raster, rasterPath); !st) return fail(st);
    }
  }
  computing.reset();
  if (asJson) {
    std::string text = "{\n\"element_order\": " + std::to_string(file->elementOrder) +
                       ",\n\"quality\": " + qualityReportToJson(q, true);
    if (file->elementOrder == 2) {
      char buf[256];
      std::snprintf(
          buf, sizeof buf,
          ",\n\"quadratic\": {\"quality_of\": \"corner tets\", \"min_jacobian_fraction\": "
          "%.17g, \"worst_scaled_jacobian\": %.17g, \"folded_elements\": %zu}",
          worst.minOverStraight, worst.minOverMax, folded);
      text += buf;
    }
    if (withFidelity) text += ",\n\"fidelity\": " + fidelityReportToJson(fr);
    text += "\n}\n";
    std::fputs(text.c_str(), stdout);
  } else {
    std::printf("%s: %zu vertices, %zu tets\n", meshPath.c_str(), mesh->points.size(), mesh->tets.size());
    if (file->elementOrder == 2)
      std::printf(
          "10-node tets: the figures below are of their corner (4-node) tets. Quadratic "
          "Jacobian at the 4 corners, 6 mid-edge nodes and centroid: smallest det J %.4f x "
          "the straight-sided value, worst scaled Jacobian (min/max det J) %.4f, %zu "
          "element(s) folded (det J <= 0)\n",
          worst.minOverStraight, worst.minOverMax, folded);
    std::fputs(qualityReportToText(q).c_str(), stdout);
    if (withFidelity) std::fputs(fidelityReportToText(fr).c_str(), stdout);
  }
  return 0;
}

int runPhantom(const std::string& output, double voxelSize, bool hip, const CLI::Option* scale,
               double scaleValue) {
  if (!hip && scale->count() > 0)
    return fail({ErrorCode::InvalidArgument, "--scale is for the hip phantom: add --hip (the "
                                             "femur phantom takes --voxel-size)"});
  if (hip && voxelSize > 0)
    return fail({ErrorCode::InvalidArgument, "--voxel-size is for the femur phantom: the hip "
                                             "phantom takes --scale (0.5: 256 x 256 x 200 voxels)"});
  CancellableCommand command;
  LabelVolume v;
  {
    ReadingScope computing;  // nothing written yet: a signal ends the process at once
    if (hip) {
      HipPhantomOptions ho;
      if (scale->count() > 0) ho.scale = scaleValue;
      v = makeHipPhantom(ho);
    } else {
      PhantomOptions po;
      if (voxelSize > 0) po.voxelSize = voxelSize;
      v = makePhantom(po);
    }
  }
  if (Status s = writeLabelMap(v, output); !s) return fail(s);
  std::fprintf(stderr, "wrote %s (%d x %d x %d voxels, %zu materials)\n", output.c_str(), v.dims[0],
               v.dims[1], v.dims[2], v.materials.size());
  return 0;
}

/// `femesher medial-axis`: the Integer Medial Axis the mesh run computes, as a label image on the
/// run's working grid (the labelled box plus a margin) in the input's physical space: each voxel
/// holds the label whose axis passes through it (-1 elsewhere; background 0 included).
int runMedialAxis(const std::string& input, const std::string& output, const std::string& labelText,
                  const std::string& prune, double gamma, double gammaConstant) {
  MeshingParameters p;
  p.sizing.mode = SizingMode::Adaptive;
  if (!prune.empty() && !parseMedialAxisPruning(prune, p.sizing.pruning))
    return fail({ErrorCode::InvalidArgument,
                 "--prune '" + prune + "': use none, constant, linear, sqrt or constant-linear"});
  if (gamma >= 0) p.sizing.gamma = gamma;
  if (gammaConstant >= 0) p.sizing.gammaConstant = gammaConstant;
  long label = 0;
  if (!labelText.empty()) {
    char* end = nullptr;
    label = std::strtol(labelText.c_str(), &end, 10);
    if (!end || *end != '\0')
      return fail({ErrorCode::InvalidArgument, "--label '" + labelText + "' is not an integer"});
  }
  CancellableCommand command;
  std::optional<ReadingScope> computing(std::in_place);  // nothing written until the image
  auto volume = readLabelMap(input);
  if (!volume) return fail(volume.status());
  RunContext& ctx = command.ctx;
  LabelVolume out;
  size_t voxels = 0;
  if (Status s = runGuarded([&] {
        MeshingRun run(volume.value(), p, ctx);
        run.runThrough(StageId::MedialAxis);
        const PreprocessedVolume& grid = run.state().grid;
        const LabelMedialAxes& axes = *run.state().medialAxes;
        out = run.workingGridGeometry();
        out.labels.assign(grid.voxelCount(), -1);
        for (size_t a = 0; a < axes.labels.size(); ++a) {
          const int32_t user = grid.userLabel[size_t(axes.labels[a])];
          if (!labelText.empty() && user != label) continue;
          for (uint32_t v : axes.axes[a].voxels) out.labels[v] = user;
          voxels += axes.axes[a].voxels.size();
        }
        if (!labelText.empty() &&
            std::find(grid.userLabel.begin(), grid.userLabel.end(), int32_t(label)) ==
                grid.userLabel.end())
          throw Error(ErrorCode::InvalidArgument,
                      "--label " + labelText + ": " + input + " has no meshed material with that "
                      "label (see `femesher info " + input + "`).");
      });
      !s)
    return fail(s);
  std::fprintf(stderr, "%zu medial voxels (pruning %s, gamma %g)\n", voxels,
               medialAxisPruningName(p.sizing.pruning), p.sizing.gamma);
  computing.reset();  // a signal from here on stops the write before its rename
  if (Status s = writeLabelMap(out, output); !s) return fail(s);
  std::fprintf(stderr, "wrote %s\n", output.c_str());
  return 0;
}

}  // namespace femesher::cli
