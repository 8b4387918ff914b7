// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file SpatialOrder.h
/// (Private to the logic library.) Z-order (Morton order) of points, and a tet mesh renumbered
/// in that order: items near each other in space get near indices, so local mesh operations and
/// sweeps over a mesh touch memory that is already in the cache.

#include <femesher/Types.h>

#include <array>
#include <cstdint>
#include <vector>

namespace femesher {
namespace internal {

/// Indices of `points` in Morton order on a grid of `cell` (from the points' lower corner; 21 bits
/// per axis), ties by index: deterministic.
std::vector<uint32_t> mortonOrder(const std::vector<Vec3>& points, double cell);

/// Renumbers a tet mesh in place: points in Morton order, then tets in the Morton order of their
/// centroids (labels follow their tets). Each tet keeps its vertex order (and so its
/// orientation); the mesh is the same, only its numbering changes.
void spatiallyRenumber(std::vector<Vec3>& points, std::vector<std::array<int32_t, 4>>& tets,
                       std::vector<int32_t>& labels);

}  // namespace internal
}  // namespace femesher
