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
#include <femesher/stages/BoundaryMesh.h>
#include <femesher/stages/IndicatorFunctions.h>
#include <femesher/stages/LabelPreprocess.h>
#include <femesher/stages/Optimize.h>
#include <femesher/stages/ParticleSystem.h>
#include <femesher/stages/SizingField.h>
#include <femesher/stages/VolumeMesh.h>

#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

namespace femesher {

/// Linear elastic properties written into solver exports (Abaqus *ELASTIC, FEBio).
struct ElasticProperties {
  double youngsModulus = 1000.0;  ///< MPa
  double poissonRatio = 0.3;
  double density = 1.0e-9;        ///< tonne/mm^3 (Abaqus mm-N-s consistent units)
};

/// The run itself: threads, randomness, evaluation.
struct RunParameters {
  int threads = 0;              ///< 0 = all cores
  uint64_t seed = 1;            ///< random seed (sampling order); same seed + threads = same mesh
  bool computeFidelity = true;  ///< compare the mesh with the labels (Dice, distances)
};

/// Everything a user can set: one parameter struct per stage (each default is defined there,
/// once), plus the run and the solver exports. The settable keys (`--set key=value`, JSON, the
/// Slicer XML, the panel) are listed in `parameterDescriptors()`, which reads and writes these
/// fields. Units are the ones each stage struct documents (voxels of the smallest spacing for
/// facet_distance and sliver_peel_distance, mm for lengths, degrees for angles).
struct MeshingParameters {
  LabelPreprocessParameters preprocess;  ///< min_voxels, excluded materials
  IndicatorParameters indicators;        ///< smoothing_sigma
  SizingParameters sizing;               ///< sizing, edge lengths, sizing_scale, h_min/h_max, ...
  ParticleSystemParameters particles;    ///< particle_iterations (its seed is `run.seed`)
  BoundaryMeshParameters boundary;       ///< facet_distance, voxel_refinement, surface_mesher
  VolumeMeshParameters volume;           ///< TetGen bounds and options
  OptimizeParameters optimize;           ///< optimize_min_dihedral, sliver_peel_distance,
                                         ///< optimize_interfaces, min_dihedral_warning
  RunParameters run;

  // --- Exports --------------------------------------------------------------------------------
  /// Default elastic properties for every material in solver exports.
  ElasticProperties defaultMaterial;
  /// Per-label overrides (user label id -> properties).
  std::map<int32_t, ElasticProperties> materialProperties;
  /// Element order of the exported tets: 1 (4 nodes) or 2 (10 nodes, straight-edge midpoints;
  /// .inp, .msh, .vtu, .vtk, .feb only). Key `element_order`.
  int elementOrder = 1;
  /// Material pairs whose interface is split into two coincident surfaces with their own nodes,
  /// written as contact pairs (io/ContactSplit.h), as (labelA, labelB) user label ids; the first
  /// label of a pair is the dependent (slave) side in the decks. Key `contact_pairs`, text
  /// "A:B,C:D"; empty = none.
  std::vector<std::pair<int32_t, int32_t>> contactPairs;
};

/// Description of one settable parameter.
struct ParameterDescriptor {
  std::string key;          ///< as used by --set and JSON, e.g. "target_edge_length"
  std::string type;         ///< "double", "int", "bool", "choice", "string"
  std::string unit;         ///< "mm", "voxels", "degrees", "" ...
  std::string defaultValue; ///< as text
  double minimum = 0, maximum = 0;  ///< valid range (inclusive) for numbers
  std::string label;        ///< short human label ("Target edge length")
  std::string help;         ///< one or two sentences for tooltips and --help
  bool advanced = false;
  std::vector<std::string> choices;  ///< for type "choice"
};

const std::vector<ParameterDescriptor>& parameterDescriptors();

/// Every settable parameter as a JSON array (what `femesher parameters --json` prints): objects
/// with key, type, unit, label, help, advanced and the default as a JSON value of the parameter's
/// type (bool, integer, double, or text for "choice"); numbers also carry their inclusive
/// minimum and maximum, choices their list of values. Doubles are written so that they read back
/// bit for bit.
std::string parameterDescriptorsToJson();

/// Boolean text as `--set` and the CLI flags accept it: true/on/yes/1 and false/off/no/0.
/// Returns false (and leaves `value` alone) for anything else.
bool parseBoolean(const std::string& text, bool& value);

/// Set one parameter from text ("target_edge_length", "1.5"). Also accepts
/// "material.<label>.E", "material.<label>.nu", "material.<label>.density", "default.E", ...,
/// "material.<label>.name" = any one-line text (the material's name in the mesh, every export and
/// the report; into `preprocess.names`) and "material.<label>.exclude" = "background" | "merge" |
/// "no" (see Exclusion).
/// Errors: InvalidArgument naming the key and the accepted range.
Status setParameter(MeshingParameters& params, const std::string& key, const std::string& value);
/// Current value as text.
std::string getParameter(const MeshingParameters& params, const std::string& key);

/// Named presets: "coarse", "default", "fine". Unknown name -> InvalidArgument.
Result<MeshingParameters> presetParameters(const std::string& name);
std::vector<std::string> presetNames();

/// JSON round trip (object of key -> value; materials under "materials": label -> {E, nu,
/// density, name, exclude}).
std::string parametersToJson(const MeshingParameters& params);
Result<MeshingParameters> parametersFromJson(const std::string& json,
                                             const MeshingParameters& base = {});
Result<MeshingParameters> loadParametersFile(const std::string& path,
                                             const MeshingParameters& base = {});

/// The text of the choice values, as keys and JSON files spell them.
std::string sizingModeName(SizingMode mode);         ///< "adaptive", "uniform"
std::string surfaceMesherName(SurfaceMesher mesher); ///< "delaunay", "ldt"
std::string exclusionName(Exclusion exclusion);      ///< "background", "merge"

/// Check ranges and consistency.
Status validate(const MeshingParameters& params);

/// Checks that every label the parameters give properties or a name (material.<label>.E, .nu,
/// .density, .name) is one of `labels`, the materials of the label map `source` (its labels other
/// than the background 0). InvalidArgument otherwise, naming the unknown labels and their keys,
/// listing the labels present and what to do. (Exclusions of absent labels are only warned
/// about, by LabelPreprocess.) `MeshingRun` calls this before any stage runs.
Status checkMaterialLabels(const MeshingParameters& params, const std::vector<int32_t>& labels,
                           const std::string& source);

}  // namespace femesher
