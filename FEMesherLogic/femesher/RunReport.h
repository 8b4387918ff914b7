// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file RunReport.h
/// The run report (`femesher mesh --report r.json`, the panel's "Save report"): input geometry and
/// label table, every parameter, per-stage wall seconds, every stage result's counts, quality and
/// fidelity figures, warnings and a status.

#include <femesher/MeshingRun.h>

#include <string>
#include <vector>

namespace femesher {

/// The report of a run that has gone through every stage, as JSON text.
std::string runReportJson(const MeshingRun& run, const std::vector<std::string>& warnings,
                          double totalSeconds);

}  // namespace femesher
