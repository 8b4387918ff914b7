// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file LocalDelaunay.h
/// The paper's side contribution, done with a true 1-ring: a surface mesher that triangulates each
/// particle's neighbourhood in its tangent plane (`--set surface_mesher=ldt`).
///
/// For every interface patch (a,b) and every particle p of it (junction particles belong to every
/// patch whose two labels they hold):
///  1. Candidates are p's natural neighbours: its neighbours in the 3-D Delaunay triangulation of
///     all particles, and theirs (2-ring), restricted to the same patch and to particles whose
///     normals agree with p's (n_p . n_q > 0.3; the two sheets of a thin layer stay apart). k
///     nearest neighbours, as in the paper, are not isotropic on graded samples and leave holes.
///  2. They are projected on p's tangent plane (normal of f_a - f_b) and triangulated (2-D
///     Delaunay, CGAL); the triangles around p form its star.
///  3. A triangle is kept when it is in the stars of at least two of its three vertices; an edge
///     used by more than two triangles of a patch loses its least-voted triangles.
///  4. Holes: an edge used by an odd number of a material's boundary triangles is open. Open
///     loops of a patch are filled by ear clipping in their mean plane; fills are counted.
/// The result is reported as holes before and after filling (open edges per material).

#include <femesher/stages/BoundaryMesh.h>
#include <femesher/stages/IndicatorFunctions.h>
#include <femesher/stages/Junctions.h>
#include <femesher/stages/ParticleSystem.h>

#include <cstdint>
#include <utility>
#include <vector>

namespace femesher {

class RunContext;

struct LocalDelaunayResult {
  std::vector<std::array<int32_t, 3>> triangles;  ///< indices into the particle list
  std::vector<std::pair<uint16_t, uint16_t>> trianglePairs;
  size_t openEdgesBefore = 0;   ///< open edges (summed over materials) before filling
  size_t holesFilled = 0;       ///< loops closed by ear clipping
  size_t openEdgesAfter = 0;    ///< what is left: 0 = watertight
  size_t nonManifoldRemoved = 0;
};

/// `delaunay` must be the labelled Delaunay built from exactly `particles` (same order).
LocalDelaunayResult buildLocalDelaunaySurface(const IndicatorField& field,
                                              const std::vector<Particle>& particles,
                                              const Junctions& junctions,
                                              const LabelledDelaunay& delaunay, RunContext& ctx);

/// Open edges of a multi-material triangle set: for every material, edges used an odd number of
/// times by the triangles bounding it (label 0 = outside is not counted).
size_t countOpenEdges(const std::vector<std::array<int32_t, 3>>& triangles,
                      const std::vector<std::pair<uint16_t, uint16_t>>& pairs);

}  // namespace femesher
