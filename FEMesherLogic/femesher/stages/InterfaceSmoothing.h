// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file InterfaceSmoothing.h
/// Part of stage 10 ("Optimize"): the smooth interfaces a run's mesh approximates, for moving
/// interface and triple-line vertices along them (Optimize.h, OptimizeInterfaces).
///
/// Vertex classes, from the mesh itself: the materials around a vertex are the labels of its
/// tets, plus the background (0) when one of its faces has no tet on the other side and is not on
/// the volume's box (the mesh's outer boundary). One material: interior; two: interface; three:
/// triple line (moves along it, unless the line's direction is unclear there); four or more:
/// junction point, which may move anywhere within a quarter of the facet distance of where it
/// is (faces around it whose interface the projection cannot find are bounded by that alone;
/// the optimizer's last resort allows 0.95 of the facet distance, see smoothInterfaceVertex). On the volume's box, only a vertex on one box plane between two materials moves:
/// along the trace of their interface on that plane (alternating projections onto the interface
/// and the plane), never leaving the plane; box edges and corners stay (the outer-boundary
/// sliding of Optimize.h keeps box-face vertices of one material on their face).
///
/// Bounds (both for vertex moves and interface edge flips): an interface triangle touched ends
/// with its centroid at most max(its distance before, a quarter of facetDistance) from its
/// interface (measured by projecting the centroid), and the net volume the operations move
/// between materials stays, with what peeling removed, within 0.5 % of each material's volume
/// (Optimize.h, "volume budgets").
///
/// Projection onto the interface of a and b: Newton on f_a - f_b along its gradient (steps of at
/// most half a voxel, at most two voxels in all), accepted when |f_a - f_b| < 1e-4 voxel and a, b
/// are the two leading materials there; onto a triple line: locateJunctionPoint (Junctions.h).

#include <femesher/stages/IndicatorFunctions.h>
#include <femesher/stages/Optimize.h>

namespace femesher {

/// The interfaces of `field` in the canonical frame (mm) of its volume, with the input's box
/// (when known) and facet distance `facetDistanceVoxels` × the smallest spacing. The callbacks
/// keep a reference to `field`, which must outlive them. Thread-safe (read-only).
OptimizeInterfaces indicatorInterfaces(const IndicatorField& field, double facetDistanceVoxels);

}  // namespace femesher
