// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/RunReport.h>
#include <femesher/Version.h>

#include <nlohmann/json.hpp>

namespace femesher {

namespace {

using json = nlohmann::json;

json geometryJson(const LabelVolume& in) {
  json g;
  g["path"] = in.sourcePath;
  g["dims"] = in.dims;
  g["spacing"] = in.spacing;
  g["origin"] = in.origin;
  g["direction"] = in.direction;
  g["space"] = "LPS";
  return g;
}

json labelsJson(const MeshingState& s) {
  const PreprocessedVolume& vol = s.grid;
  json labels = json::array();
  for (int m = 1; m <= vol.materialCount(); ++m)
    labels.push_back({{"id", vol.userLabel[m]}, {"name", vol.materials[m].name},
                      {"color", vol.materials[m].color}, {"voxels", vol.voxelCounts[m]},
                      {"in_mesh", s.meshedMaterials.count(m) > 0}});
  return labels;
}

/// The check after Optimize: the threshold, the counts and the worst tets below it (LPS
/// centroid, user label, material name, angle).
json meshCheckJson(const MeshingState& s) {
  const MeshCheckResult& c = s.meshCheck;
  const PreprocessedVolume& vol = s.grid;
  json worst = json::array();
  for (const PoorElement& e : c.worst) {
    const auto m = size_t(e.label);
    const bool known = m < vol.userLabel.size() && m < vol.materials.size();
    worst.push_back({{"centroid_lps", e.centroid},
                     {"label", known ? vol.userLabel[m] : e.label},
                     {"material", known ? vol.materials[m].name : std::string()},
                     {"min_dihedral", e.minDihedral}});
  }
  return {{"min_dihedral_warning", c.minDihedralWarning},
          {"worst_min_dihedral", c.worstMinDihedral},
          {"tets_below_warning", c.tetsBelowWarning},
          {"degenerate_tets_removed", c.removedDegenerateTets},
          {"worst_tets", worst}};
}

}  // namespace

std::string runReportJson(const MeshingRun& run, const std::vector<std::string>& warnings,
                          double totalSeconds) {
  const MeshingState& s = run.state();
  const MeshingParameters& params = run.parameters();
  json report;
  report["femesher_version"] = FEMESHER_VERSION;
  report["libraries"] = {{"ITK", FEMESHER_ITK_VERSION}, {"VTK", FEMESHER_VTK_VERSION},
                         {"CGAL", FEMESHER_CGAL_VERSION}, {"TetGen", FEMESHER_TETGEN_VERSION}};
  report["input"] = geometryJson(run.input());
  report["input"]["labels"] = labelsJson(s);
  report["input"]["dropped_labels"] = s.grid.droppedLabels;
  if (!s.grid.excludedLabels.empty()) report["input"]["excluded_labels"] = s.grid.excludedLabels;
  report["parameters"] = json::parse(parametersToJson(params));
  json stages = json::array();
  for (const auto& t : s.timings) stages.push_back({{"name", t.name}, {"seconds", t.seconds}});
  report["stages"] = stages;
  report["total_seconds"] = totalSeconds;
  if (s.memory.peakBytes > 0)
    report["memory_estimate"] = {{"peak_bytes", s.memory.peakBytes},
                                 {"available_bytes", s.memory.availableBytes},
                                 {"available_source", s.memory.availableSource},
                                 {"working_voxels", s.memory.gridVoxels},
                                 {"materials", s.memory.materials},
                                 {"interface_faces", s.memory.interfaceFaces},
                                 {"exceeds_available", s.memory.exceeds()}};
  json counts = json::object();
  for (const auto& [k, v] : run.reportCounts()) counts[k] = v;
  report["counts"] = counts;
  const std::string mesher = surfaceMesherName(params.boundary.mesher);
  const bool ldtAsked = params.boundary.mesher == SurfaceMesher::LocalDelaunay;
  report["surface_mesher"] = mesher;
  report["surface_mesher_used"] =
      ldtAsked && !s.surface.ldtUsed ? "delaunay (ldt surface not watertight)" : mesher;
  // Wall seconds of the two surface meshers inside the BoundaryMesh stage (the local Delaunay
  // one runs after, and uses, the restricted Delaunay one).
  report["surface_mesher_seconds"] = {{"restricted_delaunay", s.surface.restrictedSeconds},
                                      {"ldt", s.surface.ldtSeconds}};
  report["volume_mesh"] = {{"method", s.volumeMesh.method},
                           {"tetgen_switches", s.volumeMesh.switches},
                           {"dropped_cavity_tets", s.volumeMesh.droppedCavityTets}};
  report["quality"] = json::parse(qualityReportToJson(s.quality, true));
  if (s.hasFidelity) report["fidelity"] = json::parse(fidelityReportToJson(s.fidelity));
  // What the exports get beyond the tets: the split contact pairs and the box-face node sets.
  json contacts = json::array();
  for (const auto& c : s.contacts)
    contacts.push_back({{"labels", {c.labelA, c.labelB}},
                        {"interface_triangles", c.facesA.size()},
                        {"duplicated_nodes", c.duplicatedNodes}});
  report["contact_pairs"] = contacts;
  json boxSets = json::object();
  for (const auto& n : s.boxNodeSets) boxSets[n.name] = n.nodes.size();
  report["box_node_sets"] = boxSets;
  report["warnings"] = warnings;
  report["mesh_check"] = meshCheckJson(s);
  // "ok": no degenerate tet (a run with one fails) and every tet at or above
  // min_dihedral_warning; "poor_elements": some tet below it (mesh_check lists the worst).
  report["status"] = s.meshCheck.poor() ? "poor_elements" : "ok";
  return report.dump(2);
}

std::string addReportWarnings(const std::string& reportJson, const std::vector<std::string>& warnings) {
  if (warnings.empty()) return reportJson;
  json report = json::parse(reportJson);
  for (const auto& w : warnings) report["warnings"].push_back(w);
  return report.dump(2);
}

}  // namespace femesher
