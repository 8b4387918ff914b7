// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/StageTable.h>

namespace femesher {

const std::vector<StageInfo>& stageTable() {
  static const std::vector<StageInfo> table = {
      {StageId::LabelPreprocess, "LabelPreprocess", "Preparing labels", 2},
      {StageId::IndicatorFunctions, "IndicatorFunctions", "Smoothing the interfaces", 10},
      {StageId::MedialAxis, "MedialAxis", "Computing the medial axis", 6},
      {StageId::SizingField, "SizingField", "Computing the sizing field", 4},
      {StageId::SurfaceSampling, "SurfaceSampling", "Sampling the surfaces", 8},
      {StageId::Junctions, "Junctions", "Finding triple lines", 5},
      {StageId::ParticleSystem, "ParticleSystem", "Particles settling", 18},
      {StageId::BoundaryMesh, "BoundaryMesh", "Meshing the surfaces", 10},
      {StageId::VolumeMesh, "VolumeMesh", "Filling with tetrahedra", 28},
      {StageId::Optimize, "Optimize", "Removing slivers", 3},
      {StageId::Quality, "Quality", "Measuring quality", 3},
      {StageId::Fidelity, "Fidelity", "Comparing with the labels", 10},
  };
  return table;
}

const StageInfo& stageInfo(StageId id) { return stageTable()[size_t(id)]; }

const StageInfo* findStage(const std::string& key) {
  for (const auto& s : stageTable())
    if (key == s.key) return &s;
  return nullptr;
}

}  // namespace femesher
