// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file Optimize.h
/// Stage 10 ("Optimize"): removes slivers and other flat tets left by TetGen, towards a minimum
/// dihedral angle target, keeping the mesh conformal and its interfaces near the smooth ones.
///
/// Works on the tets whose minimum dihedral angle is below `targetMinDihedral`, worst first, with
/// these local operations. Each is applied only when it raises the smallest minimum dihedral angle
/// of the tets it replaces or moves (so the worst angle of the mesh never decreases and the
/// process terminates):
///  - edge removal (Shewchuk's edge removal, 3-to-2, 4-to-4, ... 7-to-10 flips): an edge whose
///    ring of tets all belong to one material and touch no boundary face is removed, the ring's
///    link polygon being re-triangulated optimally (dynamic programming over its triangulations);
///  - 2-to-3 face flips across a face inside one material;
///  - smoothing of interior vertices (vertices on no interface or boundary face): the vertex
///    moves to the position that maximises the worst tet of its star (Laplacian candidate, then
///    line searches along the shortest vector of the convex hull of the gradients of the star's
///    tets within 0.5 degrees of its worst, which raises all of them to first order, or along the
///    worst tet's gradient alone); a vertex of the outer boundary alone whose
///    boundary faces are flat (all their vertices within `peelDistance` of one plane) slides
///    within that plane the same way;
///  - peeling: a flat tet with a face on the mesh's outer boundary (faces with no other tet: the
///    interface with the background or the volume's box) is removed when its thickness (smallest
///    altitude) is below `peelDistance` (never a material's last tet, at most 0.4 % of a
///    material's volume in all, see "volume budgets" below; a tet at or above
///    `minDihedralWarning` is peeled only when the
///    flips below do not help, and only within three quarters of that budget, so that the flattest
///    tets, which other operations often leave late, still find some). That flips two nearly
///    coplanar boundary triangles, drops a flat
///    cap, fin or isolated tet, and moves the outer boundary by at most `peelDistance`. A cap
///    (three or four outer faces) may be as thick as the interfaces' facet distance (when given):
///    its outer faces give way to the one below them. With interfaces, a thicker tet with one to
///    three outer faces goes too when every face it uncovers has its centroid within the facet
///    distance of the interface of the tet behind it with the background (the box counts as
///    that interface), an outer face on the volume's box has its apex within the facet distance
///    of the box's plane, and the outer boundary stays a manifold (the edge or vertex it
///    uncovers is not on the boundary already).
///  - smoothing of interface vertices (given the smooth interfaces, OptimizeInterfaces, see
///    InterfaceSmoothing.h): a vertex with exactly two materials around (outside the mesh, away
///    from the volume's box, counting as background 0) moves in the tangent plane of its
///    interface triangles and is projected back onto f_a = f_b; a vertex with three materials
///    around moves along its triple line and is projected onto it. Both materials' tets move
///    with it, so the mesh stays conformal. A move is kept only when it raises the worst tet of
///    the star (see InterfaceSmoothing.h for the distance and volume bounds). A vertex with four
///    or more materials around (a junction point) moves freely within a quarter of the facet
///    distance of where it started; an interface vertex on one plane of the volume's box moves
///    along the interface's trace on that plane; box edges and corners stay;
///  - relabelling: a flat tet (thinner than `peelDistance` or, with interfaces, the facet
///    distance) with no outer face and more faces on one other material than on its own joins
///    that material (the new interface triangles within `facet_distance` where their interface
///    can be found, else no farther from the faces they replace than the tet is thick; within the
///    volume budget of interface moves); it then has fewer constrained faces and the flips above
///    can remove it; with as many or fewer, only when an edge removal or a face flip inside that
///    material then follows;
///  - interface edge flips: a flat tet with two faces on the interface with one other material
///    (its other faces inside its own) joins that material when the edge it leaves inside it can
///    then be removed (the edge removal above): the two interface triangles on that edge become
///    the tet's two other faces, whose centroids must lie within the facet distance of the
///    smooth interface (and the volume budget of interface moves holds).
///  - vertex insertion (insertVertices), when nothing above helps a tet: a new vertex replaces the
///    tet and its neighbours of the same material across unconstrained faces (one, two, then three
///    rings deep, the first that helps) by a star of tets,
///    and moves to where the star's worst tet is best; kept only when that beats the old worst.
///  - edge split (splitEdges), when insertion does not help either: the tet's edges, longest
///    first, are split at their midpoint together with every tet around the edge (any
///    material, so interface triangles on it are halved in their own plane) and the midpoint
///    moves by its class like any vertex above; kept when the worst tet around the edge rises.
///  - long edge collapse, in the inserting rounds when a split does not help either: an edge of
///    the tet up to eight facet distances long collapses onto one of its ends under the rules of
///    collapseEdges, when every interface triangle then around the kept end has its centroid
///    within the facet distance of its smooth interface (which must be found there).
///  - off-interface move, the last resort of the inserting rounds: a vertex of the tet with two
///    materials around may leave its interface, one with three its triple line, to anywhere
///    within 0.95 × the facet distance of it (pulled back to that distance; on a plane of the
///    volume's box it stays in the plane, within that distance of the interface's trace on it;
///    a junction point of four or more materials within that distance of where it started),
///    when that raises the worst tet of its star; its interface triangles' centroids stay within
///    0.95 × the facet distance of the interface (or no farther than they were) and the volume
///    bound of the moves along it holds. Around a triple-line vertex, a triangle whose own
///    interface cannot be found (the third material leads at its centroid) is measured to the
///    triple line instead, which is never nearer. Four vertices on interfaces that are nearly
///    coplanar leave no other way out; nor does a thin wedge of one material ending between two
///    others, where every tet of the wedge at the line is as flat as the wedge (the three sheets
///    are then nearly parallel and the line has no direction to slide along), until the line's
///    vertices move into the wedge.
/// Volume budgets: interface moves, relabelling, interface flips and edge collapses may change a
/// material's volume (net, either sign) and peeling may remove from it 0.5 % of that volume
/// together, peeling at most 0.4 %: what peeling leaves unused, the moves may use (a small
/// material mended by moves and collapses rather than by peeling needs it). Peeling's share
/// includes the specks a peeled tet cuts off the mesh (pieces the last step would remove as
/// floating fragments: they go with the tet), so that the stage changes no material's volume by
/// more than 0.5 % beyond the floating fragments it removes without the rounds too.
/// Then the interior is coarsened (coarsenMinDihedral, with a size function `sizeAt`): interior
/// vertices with an edge shorter than coarsenShortEdge × the size are collapsed onto a neighbour
/// when the new tets stay at or above min(coarsenMinDihedral, the star's worst) (see below).
/// With insertVertices, the tets still below the target then get the regular and inserting rounds
/// again, in their coarsened neighbourhood, as long as that raises their worst tet or lowers their
/// number (at most eight times; each operation still only raises the worst tet it touches).
/// Last resort, a tet still below `minDihedralWarning` with a face on the outer boundary is peeled
/// (with the specks it cuts off) even beyond the volume budget (optimize_over_budget_peels).
/// Floating fragments (minFragmentVoxels; ten times larger when they hold a tet below the
/// target) are removed after the rounds; those lighter than minFragmentVoxels, which go whatever
/// their tets, already before them, so that the rounds spend nothing on them.
/// Interface triangles change only by these moves and flips, which relabel or re-triangulate
/// whole tets: every interface triangle stays shared by the tets of both sides,
/// so the mesh stays conformal. The result is
/// deterministic (sequential, ordered by quality and index). All positions in mm (any frame:
/// the operations are rigid-motion invariant).

#include <femesher/Types.h>

#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <vector>

namespace femesher {

class RunContext;

struct OptimizeParameters {
  /// Tets whose minimum dihedral angle (degrees) is below this are worked on; 0 = stage off.
  double targetMinDihedral = 15.0;
  /// Rounds over the tets still below the target (each round stops early once nothing improves).
  int passes = 4;
  /// Flat tets with two to four faces on the outer boundary (background or volume box) thinner
  /// than this, in voxels of the smallest spacing, are removed (the outer boundary moves by at
  /// most that much; 0 = never); flat outer-boundary patches may slide by as much.
  double peelDistance = 0.3;
  /// The length of that voxel in the mesh's frame (mm): peelDistance × voxelSize is the distance.
  /// A run sets it from its grid's smallest spacing; 1 when the mesh is in voxel units.
  double voxelSize = 1.0;
  /// Pieces of the mesh connected to nothing else by a face (floating elements: a solver sees a
  /// rigid-body mode in each) whose volume is below this many voxels are removed, unless a
  /// material would vanish. They are specks a thin part leaves behind; 0 = keep them. A piece
  /// holding a tet below targetMinDihedral goes up to ten times this volume: all its faces are
  /// outer, so no operation can mend it, and a solver would see a bad element that floats.
  double minFragmentVoxels = 1.0;
  /// The volume of one voxel (mm^3; a run sets the product of its grid's spacings).
  double voxelVolume = 1.0;
  /// Move interior vertices.
  bool smooth = true;
  /// When nothing else helps a tet: insert a vertex in it and its same-material neighbours (the
  /// cavity), placed where the worst new tet is best; kept only when that beats the cavity.
  bool insertVertices = true;
  /// In the round that inserts vertices, when inserting inside one material does not help a tet
  /// either: split its longest edge that helps, with every tet around the edge (any material),
  /// and move the midpoint by its class (along its interface, triple line or flat outer patch, or
  /// freely). Edges on an interface or the outer boundary only with moveInterfaces and
  /// OptimizeInterfaces.
  bool splitEdges = true;
  /// Move interface and triple-line vertices along their interfaces (needs OptimizeInterfaces).
  bool moveInterfaces = true;
  /// Collapse an edge of a bad tet shorter than the facet distance (0.1 voxel
  /// without interfaces) onto one of its ends, where the edge lies on every interface the
  /// vanishing end lies on and the topology of the mesh and of each material stays the same.
  bool collapseEdges = true;
  /// Interior coarsening, after the improvement rounds (and only when they run: targetMinDihedral
  /// > 0): an interior vertex v (every tet around it of one material, no interface or outer face)
  /// is collapsed onto one of its eight nearest neighbours u when the edge is shorter than
  /// coarsenShortEdge × the target size at v, every new edge from u is at most coarsenLongEdge ×
  /// that size, the link condition holds and the worst new tet is at least
  /// min(coarsenMinDihedral, the worst tet it replaces). Interfaces, the outer boundary and every
  /// material's volume stay exactly as they are. Needs `sizeAt`; 0 = off.
  double coarsenMinDihedral = 15.0;
  double coarsenShortEdge = 1.3;
  double coarsenLongEdge = 3.0;
  /// Target edge length (mm) at a point of the mesh's frame (a run gives its sizing field).
  std::function<double(const Vec3&)> sizeAt;
  /// Degrees: after the stage, tets below this are reported and the run's status becomes
  /// "poor_elements" (MeshCheck.h; the stage itself does not read it). 0 = no warning.
  double minDihedralWarning = 5.0;
};

/// The smooth interfaces the mesh approximates, in the mesh's frame (mm). Materials are the
/// mesh's tet labels; 0 is the background, which is also what lies outside the mesh except on
/// the volume's box. A run builds it from its indicator functions (indicatorInterfaces in
/// InterfaceSmoothing.h); tests may give analytic surfaces. Empty callbacks: interfaces stay.
struct OptimizeInterfaces {
  /// Moves `p` onto the interface f_a = f_b (a < b) near it; false when that fails (no
  /// convergence, or a and b are not the two leading materials there).
  std::function<bool(int a, int b, Vec3& p)> projectOntoInterface;
  /// Moves `p` onto the triple line of the sorted materials a < b < c near it; false on failure.
  std::function<bool(const std::array<int, 3>& abc, Vec3& p)> projectOntoJunction;
  /// The volume's box (mm); with hasBox, vertices on it never move along an interface and mesh
  /// faces on it are not interfaces.
  Vec3 boxLo{{0, 0, 0}}, boxHi{{0, 0, 0}};
  bool hasBox = false;
  /// A vertex within this distance (mm) of a box plane is on the box.
  double boxTolerance = 0;
  /// Largest distance (mm) of an interface triangle's centroid from its smooth interface after a
  /// move (the boundary stage's facet_distance); a move breaking it is refused.
  double facetDistance = 0;
  bool enabled() const { return bool(projectOntoInterface) && facetDistance > 0; }
  /// The planes of the box (bit 2a: low side of axis a, 2a + 1: high side) p lies on (within
  /// boxTolerance); 0 without a box.
  int boxPlanes(const Vec3& p) const {
    int mask = 0;
    if (hasBox)
      for (size_t a = 0; a < 3; ++a) {
        if (std::fabs(p[a] - boxLo[a]) <= boxTolerance) mask |= 1 << (2 * a);
        if (std::fabs(p[a] - boxHi[a]) <= boxTolerance) mask |= 2 << (2 * a);
      }
    return mask;
  }
};

struct OptimizeResult {
  size_t tetsBelowTargetBefore = 0, tetsBelowTargetAfter = 0;
  size_t tetsBelow5Before = 0, tetsBelow5After = 0;
  double minDihedralBefore = 0, minDihedralAfter = 0;  ///< degrees
  size_t edgeRemovals = 0;      ///< n-to-(2n-4) flips (n = 3..7)
  size_t faceFlips = 0;         ///< 2-to-3 flips
  size_t smoothedVertices = 0;  ///< interior (and flat outer-patch) vertex moves
  size_t interfaceVertices = 0;   ///< interface vertex moves (two materials)
  size_t tripleLineVertices = 0;  ///< triple-line vertex moves
  size_t junctionVertices = 0;    ///< moves of junction points (four or more materials)
  size_t offInterfaceMoves = 0;   ///< last-resort moves of an interface vertex off its interface
  size_t interfaceFlips = 0;      ///< interface edge flips
  size_t peeledTets = 0;        ///< flat boundary tets removed
  size_t overBudgetPeels = 0;   ///< of those, tets below the warning angle peeled beyond the budget
  size_t relabelledTets = 0;    ///< flat interface tets given to the neighbouring material
  size_t insertedVertices = 0;  ///< vertices inserted (see insertVertices)
  size_t collapsedEdges = 0;    ///< short edges collapsed (see collapseEdges)
  size_t splitEdges = 0;        ///< edges split (see splitEdges)
  size_t coarsenedVertices = 0; ///< interior vertices removed by coarsening (coarsenMinDihedral)
  size_t fragments = 0;         ///< floating fragments removed (see minFragmentVoxels)
  size_t fragmentTets = 0;      ///< their tets
  double fragmentVolume = 0;    ///< their volume, mm^3
  int passes = 0;               ///< rounds run
};

/// Report figures: optimize_tets_below_target_before/after, optimize_tets_below_5deg_before/after,
/// optimize_min_dihedral_before/after, optimize_edge_removals, optimize_face_flips,
/// optimize_smoothed_vertices, optimize_interface_vertex_moves, optimize_triple_line_vertex_moves,
/// optimize_junction_vertex_moves,
/// optimize_interface_flips, optimize_peeled_tets, optimize_over_budget_peels,
/// optimize_relabelled_tets,
/// optimize_inserted_vertices, optimize_collapsed_edges, optimize_split_edges,
/// optimize_coarsened_vertices,
/// optimize_fragments_removed, optimize_fragment_tets, optimize_fragment_volume_mm3, optimize_passes.
ReportCounts reportCounts(const OptimizeResult& result);

/// Erases the tets flagged in `erase` (one flag per tet) and the points no tet uses any more;
/// tets and points keep their order, indices are renumbered.
void eraseTets(std::vector<Vec3>& points, std::vector<std::array<int32_t, 4>>& tets,
               std::vector<int32_t>& labels, const std::vector<char>& erase);

/// Minimum dihedral angle of a tet in degrees; -1 when it is not positively oriented (or flat).
double tetMinDihedral(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d);
/// The cosine of that angle (largest cosine of a dihedral angle; no acos, for comparisons); 2 when
/// the tet is not positively oriented (or flat).
double tetMaxDihedralCos(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d);
/// tetMinDihedral from tetMaxDihedralCos's value (monotone: a larger cosine is never a larger angle).
double cosToDegrees(double maxCos);

/// Improves the mesh in place. `tets` must be positively oriented; `labels` holds one material
/// per tet. Tets removed by peeling are erased and points no tet uses any more are dropped
/// (indices renumbered, order kept). Cancel is checked between operations.
OptimizeResult optimizeTetMesh(std::vector<Vec3>& points, std::vector<std::array<int32_t, 4>>& tets,
                               std::vector<int32_t>& labels, const OptimizeParameters& params,
                               RunContext& ctx);
/// The same, moving interface vertices along `interfaces` (see above).
OptimizeResult optimizeTetMesh(std::vector<Vec3>& points, std::vector<std::array<int32_t, 4>>& tets,
                               std::vector<int32_t>& labels, const OptimizeParameters& params,
                               const OptimizeInterfaces& interfaces, RunContext& ctx);

}  // namespace femesher
