// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file LabelPreprocess.h
/// Stage 1 ("Binarization" in the paper): crop the label map to its labelled voxels plus a margin,
/// compact the label ids to 0..N (0 = not meshed: background or outside), drop labels with fewer
/// than `minVoxels` voxels (their voxels join the most common neighbouring kept label; each drop
/// is reported as a warning naming the label), and apply the user's exclusions (an excluded
/// material becomes background or merges into its neighbour, see `Exclusion`).
///
/// A label map without any 0 is legal: every label is a material and the outer boundary is the
/// volume's box (the padding margin provides the outside).
///
/// The material table of the result names each material after the user's name for it
/// (`names`), else the label map's own name, else "label N".

#include <femesher/Types.h>
#include <femesher/WorkingGrid.h>

#include <array>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace femesher {

class RunContext;

/// What becomes of a material the user excluded from the mesh.
enum class Exclusion {
  Background,          ///< its voxels become background: it leaves a cavity (or is cut away)
  MergeIntoNeighbour,  ///< its voxels join the most common neighbouring kept material
};

struct LabelPreprocessParameters {
  /// Labels with fewer voxels are dropped with a warning naming them (their voxels join the most
  /// common neighbouring kept label). Every other label appears in the mesh.
  int64_t minVoxels = 10;
  int margin = 3;  ///< voxels of padding around the labelled box (>= 2); not a user parameter
  /// Materials excluded by the user (user label id -> what becomes of its voxels). A merged
  /// material's warning names the material(s) its voxels joined.
  std::map<int32_t, Exclusion> excluded;
  /// Material names given by the user (user label id -> name, `material.<label>.name`): they
  /// replace the names the label map brings (a .seg.nrrd's segment names, a colour table's, or
  /// "label N") in the material table of the working grid, hence of the mesh, every export and
  /// the run report. Empty names are ignored.
  std::map<int32_t, std::string> names;
};

/// The working grid of all later stages (see WorkingGrid.h for its frames) and its labels.
struct PreprocessedVolume : WorkingGrid {
  std::vector<uint16_t> labels;      ///< compact ids, x fastest
  std::vector<int32_t> userLabel;    ///< compact id -> user label id (entry 0: 0)
  std::vector<Material> materials;   ///< compact id -> material (entry 0: background)
  std::vector<size_t> voxelCounts;   ///< compact id -> voxels in the working grid
  std::vector<int32_t> droppedLabels;   ///< user ids dropped by minVoxels
  std::vector<int32_t> excludedLabels;  ///< user ids excluded by the user (either way)

  int materialCount() const { return int(userLabel.size()) - 1; }  ///< excluding 0
  uint16_t at(int i, int j, int k) const { return labels[index(i, j, k)]; }
};

/// Runs the stage. Throws Error(EmptyLabelMap) when nothing is left to mesh.
PreprocessedVolume preprocessLabels(const LabelVolume& input, const LabelPreprocessParameters& params,
                                    RunContext& ctx);

}  // namespace femesher
