// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file InterfaceSmoothing.h
/// Part of stage 10 ("Optimize"): the smooth interfaces a run's mesh approximates, for moving
/// interface and triple-line vertices along them (Optimize.h, OptimizeInterfaces).
///
/// Vertex classes, from the mesh itself: the materials around a vertex are the labels of its
/// tets, plus the background (0) when one of its faces has no tet on the other side (the mesh's
/// outer boundary). One material: interior; two: interface; three: triple line; four or more:
/// fixed. A vertex on the volume's box never moves along an interface (the outer-boundary
/// sliding of Optimize.h keeps box-face vertices on their face).
///
/// Bounds (both for vertex moves and interface edge flips): an interface triangle touched ends
/// with its centroid at most max(its distance before, a quarter of facetDistance) from its
/// interface (measured by projecting the centroid), and the net volume the operations move
/// between materials stays within 0.1 % of each material's volume.
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
