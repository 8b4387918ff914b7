// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file Parameters.h
/// `MeshingParameters`: everything a user can set, in physical units, with defaults. The CLI
/// (`--set key=value`, `--preset`, a JSON parameter file), the panel and the Slicer adapter all
/// fill this one struct. Values the program derives (grids, tolerances) are not in here.
///
/// Every field is also described in `parameterDescriptors()` (key, unit, default, range, help),
/// which drives `--set`, JSON load/save, the Slicer XML and the GUI tooltips.

#include <femesher/Status.h>

#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace femesher {

/// Linear elastic properties written into solver exports (Abaqus *ELASTIC, FEBio).
struct ElasticProperties {
  double youngsModulus = 1000.0;  ///< MPa
  double poissonRatio = 0.3;
  double density = 1.0e-9;        ///< tonne/mm^3 (Abaqus mm-N-s consistent units)
};

struct MeshingParameters {
  // --- Preprocessing -------------------------------------------------------------------------
  /// Labels with fewer voxels are dropped (their voxels join the most common neighbouring label),
  /// with a warning naming them. Every other label appears in the mesh.
  int64_t minVoxels = 10;

  // --- Indicator functions ---------------------------------------------------------------------
  /// Gaussian smoothing of each material's signed distance, in voxels (0 = none: the trilinear
  /// signed distance, already sub-voxel). Larger values smooth more but shrink thin and small
  /// labels (Dice drops); 0.3 keeps every voxel centre well inside its label.
  double smoothingSigma = 0.3;

  // --- Surface sampling (first meshing path) -----------------------------------------------------
  /// Target edge length of the interface triangles in mm. 0 = automatic
  /// (`edgeLengthFactor` x mean voxel spacing).
  double targetEdgeLength = 0.0;
  /// Automatic edge length as a multiple of the mean voxel spacing (used when
  /// targetEdgeLength == 0). Presets: coarse 4.5, default 3, fine 2. Detail below this size comes
  /// from the sizing field and the facet-distance refinement.
  double edgeLengthFactor = 3.0;

  // --- Sizing field (medial axis) ----------------------------------------------------------------
  /// "adaptive": target edge length from the Integer Medial Axis local feature size
  /// (h = clamp(sizing_scale x lfs, h_min, h_max), graded); "uniform": one edge length everywhere.
  std::string sizing = "adaptive";
  double sizingScale = 1.25;  ///< epsilon: h = epsilon x local feature size
  double sizingHMin = 0;      ///< mm; 0 = automatic (half the uniform edge length)
  double sizingHMax = 0;      ///< mm; 0 = automatic (edge_length_factor x 2.5 x mean spacing)
  double gradation = 0.4;     ///< Lipschitz bound: h grows at most this many mm per mm
  /// Hand the sizing field to TetGen as point metrics (-m) so the interior follows it too (more
  /// tets); off: the interior is graded by TetGen's quality bound from the surface.
  bool volumeSizing = false;

  // --- Junctions and particle system ---------------------------------------------------------
  /// Particle-system iterations (0 = use the Poisson-disk samples as they are).
  int particleIterations = 15;
  /// Surface mesher: "delaunay" (restricted Delaunay of the particles) or "ldt" (local Delaunay
  /// triangulation in tangent space, natural-neighbour 1-rings).
  std::string surfaceMesher = "delaunay";
  /// Surface approximation bound, in voxels of the smallest spacing: after the particle system,
  /// the restricted Delaunay surface is refined (points inserted on the interface) until every
  /// interface triangle's centroid lies within this distance of the implicit interface (what
  /// CGAL calls facet_distance). 0 = no refinement.
  double facetDistance = 0.5;
  /// After the facet-distance refinement, insert interface points until every voxel centre next
  /// to another label lies in a tet of its own label (Dice close to 1; more surface points).
  bool voxelRefinement = true;

  // --- Volume meshing (TetGen) ------------------------------------------------------------------
  /// TetGen quality bound: maximum radius-edge ratio (-q). 0 disables quality refinement.
  double maxRadiusEdgeRatio = 2.0;
  /// TetGen quality bound: minimum dihedral angle in degrees (-q ratio/angle).
  double minDihedralAngle = 12.0;
  /// Maximum tet volume in mm^3 (-a). 0 = automatic (from the edge length: 4 x regular tet).
  double maxTetVolume = 0.0;
  /// Keep the interface triangles exactly (TetGen -Y). If TetGen cannot, the run falls back to
  /// allowing boundary Steiner points and reports it.
  bool preserveInterfaces = true;
  /// Optimisation level of TetGen's mesh improvement (-O), 0..10.
  int optimizationLevel = 3;
  /// With preserve_interfaces: one TetGen run per material, several side by side (faster on
  /// several cores; the runs share the unsplit interface triangles, so the mesh is conformal).
  bool volumePerMaterial = true;

  // --- Optimisation (after TetGen) -----------------------------------------------------------
  /// Tets with a minimum dihedral angle below this (degrees) are improved by flips inside one
  /// material, interior-vertex smoothing and peeling (see stages/Optimize.h). 0 = off.
  double optimizeMinDihedral = 15.0;
  /// Flat tets with two or three faces on the outer boundary are removed when thinner than this,
  /// in voxels of the smallest spacing (the outer boundary moves by at most that). 0 = never.
  double sliverPeelDistance = 0.1;

  // --- Run ------------------------------------------------------------------------------------
  int threads = 0;     ///< 0 = all cores
  uint64_t seed = 1;   ///< random seed (sampling order); same seed + threads = same mesh
  bool computeFidelity = true;  ///< compare the mesh with the labels (Dice, distances)

  // --- Exports --------------------------------------------------------------------------------
  /// Default elastic properties for every material in solver exports.
  ElasticProperties defaultMaterial;
  /// Per-label overrides (user label id -> properties).
  std::map<int32_t, ElasticProperties> materialProperties;
};

/// Description of one settable parameter.
struct ParameterDescriptor {
  std::string key;          ///< as used by --set and JSON, e.g. "target_edge_length"
  std::string type;         ///< "double", "int", "bool", "choice"
  std::string unit;         ///< "mm", "voxels", "degrees", "" ...
  std::string defaultValue; ///< as text
  double minimum = 0, maximum = 0;  ///< valid range (inclusive) for numbers
  std::string label;        ///< short human label ("Target edge length")
  std::string help;         ///< one or two sentences for tooltips and --help
  bool advanced = false;
  std::vector<std::string> choices;  ///< for type "choice"
};

const std::vector<ParameterDescriptor>& parameterDescriptors();

/// Set one parameter from text ("target_edge_length", "1.5"). Also accepts
/// "material.<label>.E", "material.<label>.nu", "material.<label>.density", "default.E", ...
/// Errors: InvalidArgument naming the key and the accepted range.
Status setParameter(MeshingParameters& params, const std::string& key, const std::string& value);
/// Current value as text.
std::string getParameter(const MeshingParameters& params, const std::string& key);

/// Named presets: "coarse", "default", "fine". Unknown name -> InvalidArgument.
Result<MeshingParameters> presetParameters(const std::string& name);
std::vector<std::string> presetNames();

/// JSON round trip (object of key -> value; materials under "materials").
std::string parametersToJson(const MeshingParameters& params);
Result<MeshingParameters> parametersFromJson(const std::string& json,
                                             const MeshingParameters& base = {});
Result<MeshingParameters> loadParametersFile(const std::string& path,
                                             const MeshingParameters& base = {});

/// Check ranges and consistency.
Status validate(const MeshingParameters& params);

}  // namespace femesher
