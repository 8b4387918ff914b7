// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file StageTable.h
/// The stages of a meshing run in run order (DESIGN.md's stage table): an id, the key used in the
/// run report and by RunContext progress ("SizingField"), a human title for progress bars
/// ("Computing the sizing field") and a relative progress weight. The pipeline, the run report
/// and the panel all read this one table.

#include <string>
#include <utility>
#include <vector>

namespace femesher {

enum class StageId {
  LabelPreprocess,
  IndicatorFunctions,
  MedialAxis,
  SizingField,
  SurfaceSampling,
  Junctions,
  ParticleSystem,
  BoundaryMesh,
  VolumeMesh,
  Optimize,
  Quality,
  Fidelity,
};

struct StageInfo {
  StageId id;
  const char* key;    ///< report and progress name, e.g. "ParticleSystem"
  const char* title;  ///< human, e.g. "Particles settling"
  double weight;      ///< relative share of a typical run's progress bar
};

/// Every stage in run order.
const std::vector<StageInfo>& stageTable();
const StageInfo& stageInfo(StageId id);
/// The stage with this key; nullptr when there is none.
const StageInfo* findStage(const std::string& key);

}  // namespace femesher
