// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// The inspection subcommands: `femesher info`, `quality`, `phantom` and `medial-axis`.
#include <string>

namespace CLI {
class Option;
}

namespace femesher::cli {

/// `femesher info`: geometry, labels, voxels, components and junction cells of a label map.
int runInfo(const std::string& input, const std::string& labelNames, bool asJson);

/// `femesher quality`: element quality of a mesh (and fidelity against a label map, --raster).
int runQuality(const std::string& meshPath, const std::string& labelsPath,
               const std::string& rasterPath, bool asJson);

/// `femesher phantom`: the built-in femur phantom, or with `hip` the clinical-size hip phantom.
int runPhantom(const std::string& output, double voxelSize, bool hip, const CLI::Option* scale,
               double scaleValue);

/// `femesher medial-axis`: the Integer Medial Axis the mesh run computes, as a label image on the
/// run's working grid (the labelled box plus a margin) in the input's physical space: each voxel
/// holds the label whose axis passes through it (-1 elsewhere; background 0 included).
int runMedialAxis(const std::string& input, const std::string& output, const std::string& labelText,
                  const std::string& prune, double gamma, double gammaConstant);

}  // namespace femesher::cli
