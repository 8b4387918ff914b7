// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file ParticleSystem.h
/// Stage 7 ("Particle System"): dynamic particles on every material interface (Meyer, Kirby &
/// Whitaker 2007; Meyer et al. 2008), spaced by the sizing field.
///
/// - Constraint: a particle of interface (a,b) lives on F_ab = f_a - f_b = 0 (Newton projection
///   x <- x - F grad F / |grad F|^2) where a and b are the two leading materials; a particle that
///   cannot be projected there is removed.
/// - Energy: cotangent kernel E(r) = cot(pi r / 2 s) + pi r / 2 s - pi / 2 for r < s, 0 beyond,
///   with s = k * min(h_i, h_j) (k = `kernelScale`) from the sizing field h. Neighbours are the
///   particles of the same interface whose normals agree (n_i . n_j > 0.5, so the two sheets of a
///   thin layer do not interact) and the fixed junction particles whose label set contains a, b.
/// - Dynamics: Jacobi descent on the tangent plane with a damped Newton step (tangential force
///   over the summed kernel stiffness, times a per-particle factor that grows x1.25 on success and
///   shrinks x0.5 on failure; the energy must decrease after re-projection, else the step is
///   retried shorter). Every update reads the previous iteration's positions only, so the result
///   does not depend on the number of threads.
/// - Population: every `populationInterval` iterations a particle with far less than the ideal
///   (hexagonal) energy splits (new particle at half a spacing in a seeded tangent direction, kept
///   only where there is room), a particle with far more than the ideal energy is removed unless a
///   neighbour already is, and of two particles closer than `minSpacingFactor` x h the one with
///   the higher id is removed.
/// - At the end, a surface particle closer than a quarter of h to a junction particle or to an
///   earlier particle of any interface is removed: the rules above see one interface at a time,
///   and where interfaces meet two particles could otherwise end a hair apart.
/// - Convergence (reported): the 95th percentile of the moves is below `tolerance` x h for 3
///   iterations in a row and the population did not change in the last population step, or
///   `maxIterations` is reached. (The largest move is reported too: a few particles at the rim of
///   a patch keep sliding while their energy still decreases.)
/// Junction particles never move.

#include <femesher/Types.h>
#include <femesher/stages/IndicatorFunctions.h>
#include <femesher/stages/Junctions.h>
#include <femesher/stages/SurfaceSampling.h>

#include <cstdint>
#include <vector>

namespace femesher {

class RunContext;

struct ParticleSystemParameters {
  int maxIterations = 15;  ///< 0 = no system: the Poisson-disk samples are used as they are
  int populationInterval = 5;
  double kernelScale = 1.5;       ///< interaction radius / target spacing
  double maxStepFactor = 0.3;     ///< largest move per iteration / h
  double tolerance = 0.04;        ///< convergence: 95th percentile of moves / h
  double minSpacingFactor = 0.45; ///< closer pairs are thinned
  double splitEnergyFactor = 0.1; ///< split when energy < factor x ideal energy
  double deleteEnergyFactor = 1.5; ///< delete when energy > factor x ideal energy (crowded)
  uint64_t seed = 1;
};

struct Particle {
  Vec3 local;                 ///< local voxel index position
  uint16_t a = 0, b = 0;      ///< interface (compact labels, a < b); for junctions: first two
  int32_t junction = -1;      ///< index into Junctions::particles when fixed, else -1
};

struct ParticleSystemResult {
  std::vector<Particle> particles;  ///< junction particles first, then surface particles
  int iterations = 0;
  bool converged = false;
  double finalEnergy = 0;           ///< total energy of the surface particles
  double meanSpacingRatio = 0;      ///< mean nearest-neighbour distance / h (surface particles)
  double finalMaxMove = 0, finalMoveP95 = 0;  ///< last iteration's moves / h
  size_t added = 0, removed = 0, lost = 0;
};

/// Report figures: particle_iterations, particle_converged, particle_energy,
/// particle_spacing_ratio.
ReportCounts reportCounts(const ParticleSystemResult& result);

/// The fixed junction particles, in the order of `junctions.particles`.
std::vector<Particle> junctionParticles(const Junctions& junctions);

ParticleSystemResult runParticleSystem(const IndicatorField& field, const SurfaceSamples& seeds,
                                       const Junctions& junctions, const SizingFunction& sizing,
                                       const LabelVolume& input,
                                       const ParticleSystemParameters& params, RunContext& ctx);

}  // namespace femesher
