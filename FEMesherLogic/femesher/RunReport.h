// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file RunReport.h
/// The run report (`femesher mesh --report r.json`, the panel's "Save report"): input geometry and
/// label table, every parameter, per-stage wall seconds, every stage result's counts, quality and
/// fidelity figures, the mesh check after Optimize (`mesh_check`: min_dihedral_warning,
/// worst_min_dihedral, tets_below_warning, degenerate_tets_removed, worst_tets with centroid_lps,
/// label, material, min_dihedral), the split contact pairs (`contact_pairs`: labels,
/// interface_triangles, duplicated_nodes per pair), the node count of each non-empty box-face
/// node set (`box_node_sets`: BOX_XMIN ... BOX_ZMAX), warnings and a status: "ok" when no tet is below
/// min_dihedral_warning (and none is degenerate: such a run fails), else "poor_elements".

#include <femesher/MeshingRun.h>

#include <string>
#include <vector>

namespace femesher {

/// The report of a run that has gone through every stage, as JSON text.
std::string runReportJson(const MeshingRun& run, const std::vector<std::string>& warnings,
                          double totalSeconds);

/// The report `reportJson` with `warnings` appended to its "warnings" (e.g. the exports' warnings,
/// known only once the outputs are written: `defaultPropertiesWarning`).
std::string addReportWarnings(const std::string& reportJson, const std::vector<std::string>& warnings);

}  // namespace femesher
