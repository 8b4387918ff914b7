// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file Junctions.h
/// Stage 6 ("Crossing seeds"): triple lines (three materials meet, background included) and
/// quadruple points (four meet), found on the label grid and located on the smooth indicator
/// functions.
///
/// Every dual cell (2x2x2 voxel centres) holding >= 3 distinct labels contains a piece of a triple
/// line. For each label triple {a,b,c} of such a cell, a point with f_a = f_b = f_c is found by
/// Gauss-Newton on (f_a - f_b, f_a - f_c) with the minimum-norm step, started at the cell centre,
/// and kept when it converges inside the cell with a, b, c the three leading materials. Cells with
/// >= 4 labels are searched the same way for f_a = f_b = f_c = f_d (Newton on three equations).
/// Junctions with the volume border are included (outside the grid is background).
///
/// Sampling: quadruple points are all kept; triple-line points are thinned to the sizing field's
/// spacing (Poisson-disk along each line, away from quadruple points), then relaxed along the line
/// by a 1-D particle system (each particle moves along the line tangent towards the midpoint of its
/// two neighbours and is projected back). These particles are then held fixed.

#include <femesher/Types.h>
#include <femesher/stages/IndicatorFunctions.h>

#include <array>
#include <cstdint>
#include <functional>
#include <vector>

namespace femesher {

class RunContext;

/// Target spacing (mm) at a canonical position.
using SizingFunction = std::function<double(const Vec3& canonical)>;

struct JunctionPoint {
  Vec3 local;                   ///< local voxel index position
  std::array<uint16_t, 4> labels{{0, 0, 0, 0}};  ///< sorted compact labels (3 used for triples)
  uint8_t count = 3;            ///< 3 = triple line, 4 = quadruple point
  bool contains(uint16_t a, uint16_t b) const {
    bool ha = false, hb = false;
    for (int i = 0; i < count; ++i) {
      ha |= labels[i] == a;
      hb |= labels[i] == b;
    }
    return ha && hb;
  }
};

struct JunctionParameters {
  double spacingFactor = 1.0;  ///< junction spacing = factor x sizing field
  int relaxIterations = 10;    ///< 1-D relaxation iterations
};

struct Junctions {
  std::vector<JunctionPoint> candidates;  ///< every located point (one per cell and triple)
  std::vector<JunctionPoint> particles;   ///< the fixed junction particles (sampled)
  size_t tripleCells = 0, quadrupleCells = 0;
  size_t quadruplePoints = 0;             ///< among `particles`
};

/// Moves `local` (local voxel index position) onto the junction of the n = 3 (triple line) or 4
/// (quadruple point) sorted compact `labels`, as the candidates are located (Gauss-Newton on the
/// differences of their indicator functions, steps of at most half a voxel). True when it
/// converged with these labels the n leading materials there.
bool locateJunctionPoint(const IndicatorField& field, const uint16_t* labels, int n, Vec3& local);

/// Report figures: junction_cells, quadruple_cells, junction_particles, quadruple_points.
ReportCounts reportCounts(const Junctions& junctions);

Junctions findJunctions(const IndicatorField& field, const SizingFunction& sizing,
                        const JunctionParameters& params, RunContext& ctx);

}  // namespace femesher
