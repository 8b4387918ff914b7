// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file OptimizeEditor.h
/// Internal to the Optimize stage (Optimize.cxx, InterfaceSmoothing.cxx): the mutable tet mesh
/// the operations edit, and the vertex move they share. Positions in mm (canonical frame in a run).

#include <femesher/VecMath.h>
#include <femesher/stages/Optimize.h>

#include <algorithm>
#include <cmath>
#include <array>
#include <cstdint>
#include <functional>
#include <unordered_map>
#include <vector>

namespace femesher {
namespace optimize_detail {

constexpr double kEps = 1e-6;  // degrees: smallest improvement that counts
constexpr double kRadToDeg = 57.29577951308232;
constexpr double kDegToRad = 1 / kRadToDeg;
/// Share of a material's volume that the operations may change in all: the net volume interface
/// moves, relabelling, interface flips and edge collapses add or take (Editor::movedVolume,
/// counted by its size) plus the volume peeling removes (Editor::moveFits, peelFits).
constexpr double kVolumeBudget = 5e-3;
/// Share of a material's volume that peeling may remove in all (within kVolumeBudget).
constexpr double kPeelBudget = 4e-3;

/// Mutable tet mesh with vertex -> tet incidence; faces are found by intersecting incidences.
class Editor {
 public:
  Editor(std::vector<Vec3>& p, std::vector<std::array<int32_t, 4>>& t, std::vector<int32_t>& l)
      : pts(p), tets(t), labels(l), alive(t.size(), 1), around(p.size()),
        fixedState(p.size(), -1), stamped(p.size(), 0) {
    for (size_t i = 0; i < tets.size(); ++i)
      for (int32_t v : tets[i]) around[size_t(v)].push_back(uint32_t(i));
    for (int32_t l : labels) {
      if (size_t(l) >= perLabel.size()) perLabel.resize(size_t(l) + 1, 0);
      ++perLabel[size_t(l)];
    }
    startVolume.assign(perLabel.size(), 0);
    movedVolume.assign(perLabel.size(), 0);
    peeledVolume.assign(perLabel.size(), 0);
    for (size_t i = 0; i < tets.size(); ++i) startVolume[size_t(labels[i])] += volume(uint32_t(i));
  }

  /// True when material l's net moved volume may change by `change` (mm^3): the new |net moved
  /// volume| and the volume peeled from it stay within kVolumeBudget of its start volume together.
  /// No change always fits (a material over its budget must not stop the moves of the others).
  bool moveFits(size_t l, double change) const {
    if (change == 0) return true;
    const bool fits = fitsBudget(l, movedVolume[l], change);
    if (budgetLog) budgetLog->push_back({uint32_t(l), true, fits, change});
    return fits;
  }
  /// Books a vertex move's net volume change of material l (mm^3).
  void bookMove(size_t l, double change) {
    movedVolume[l] += change;
    if (budgetLog) budgetLog->push_back({uint32_t(l), false, false, change});
  }
  /// A budget question moveFits answered (`question`) or a change bookMove booked, in the order
  /// they came (see budgetLog).
  struct BudgetEvent {
    uint32_t label;
    bool question, answer;
    double amount;
  };
  /// When set, moveFits and bookMove record what they were asked and booked: a vertex move made
  /// on a copy of part of the mesh (Optimize's speculative moves) is then checked against the
  /// budgets as they are later (budgetsAgree) and booked on them (replayBookings).
  std::vector<BudgetEvent>* budgetLog = nullptr;
  /// True when moveFits, asked the questions of `log` in turn after its earlier bookings, would
  /// answer each as the log says on the budgets as they are now.
  bool budgetsAgree(const std::vector<BudgetEvent>& log) const {
    thread_local std::vector<double> moved;
    moved = movedVolume;
    for (const auto& e : log) {
      if (!e.question) {
        moved[e.label] += e.amount;
      } else if (fitsBudget(e.label, moved[e.label], e.amount) != e.answer) {
        return false;
      }
    }
    return true;
  }
  /// moveFits's rule for material l with `moved` as its net moved volume.
  bool fitsBudget(size_t l, double moved, double change) const {
    return std::fabs(moved + change) + peeledVolume[l] <= kVolumeBudget * startVolume[l];
  }
  /// Books the changes of `log` in turn (as bookMove did where the log was made).
  void replayBookings(const std::vector<BudgetEvent>& log) {
    for (const auto& e : log)
      if (!e.question) movedVolume[e.label] += e.amount;
  }
  /// True when `v` mm^3 may pass from material `from` to material `to` (a tet relabelled).
  bool transferFits(size_t from, size_t to, double v) const {
    return moveFits(from, -v) && moveFits(to, v);
  }
  /// Books `v` mm^3 passed from material `from` to material `to`.
  void transfer(size_t from, size_t to, double v) {
    movedVolume[from] -= v;
    movedVolume[to] += v;
  }
  /// True when peeling `v` mm^3 more from material l stays within `share` of kPeelBudget of its
  /// start volume, and within kVolumeBudget together with its net moved volume.
  bool peelFits(size_t l, double v, double share) const {
    return peeledVolume[l] + v <= share * kPeelBudget * startVolume[l] &&
           peeledVolume[l] + v + std::fabs(movedVolume[l]) <= kVolumeBudget * startVolume[l];
  }

  std::vector<Vec3>& pts;
  std::vector<std::array<int32_t, 4>>& tets;
  std::vector<int32_t>& labels;
  std::vector<char> alive;
  std::vector<std::vector<uint32_t>> around;  // alive tets per vertex
  std::vector<int8_t> fixedState;             // -1 unknown, 0 free, 1 on a boundary/interface
  std::vector<std::array<int32_t, 2>> starFaces;  // scratch of fixedVertex
  std::vector<size_t> perLabel;
  /// Per material: volume at the start, the net volume interface moves and relabelling added so
  /// far, and the volume peeling removed (mm^3).
  std::vector<double> startVolume, movedVolume, peeledVolume;
  /// smoothVertex also ascends along the shortest vector of the hull of the nearly-worst tets'
  /// gradients (set for the inserting rounds: the tets the cheaper moves could not mend).
  bool hullAscent = false;
  /// Where each junction point that moved started (junction points stay near it).
  std::unordered_map<int32_t, Vec3> junctionStart;
  /// Change stamps, for vertex moves found ahead of time (Optimize's rounds): every change stamps
  /// the vertices it touches (a tet killed, revived, added or relabelled: its four vertices; a
  /// vertex moved: itself) with `stamp`. Raising `stamp` starts a new period; what was read from
  /// the mesh before that still holds while none of the vertices read carries the new stamp.
  uint32_t stamp = 0;
  std::vector<uint32_t> stamped;
  void touch(int32_t v) { stamped[size_t(v)] = stamp; }
  bool untouched(int32_t v) const { return stamped[size_t(v)] != stamp; }

  double volume(uint32_t t) const { return volume(tets[t]); }
  /// Signed volume of the tet T (positive when positively oriented).
  double volume(const std::array<int32_t, 4>& T) const {
    const Vec3 &a = pts[size_t(T[0])], &b = pts[size_t(T[1])], &c = pts[size_t(T[2])],
               &d = pts[size_t(T[3])];
    const Vec3 u{b[0] - a[0], b[1] - a[1], b[2] - a[2]}, v{c[0] - a[0], c[1] - a[1], c[2] - a[2]},
        w{d[0] - a[0], d[1] - a[1], d[2] - a[2]};
    return (u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0]) +
            u[2] * (v[0] * w[1] - v[1] * w[0])) / 6;
  }

  /// Smallest altitude of tet t (3 V / largest face area, mm): how far it is from flat.
  double thickness(uint32_t t) const {
    double area = 0;
    for (int k = 0; k < 4; ++k) {
      const auto f = face(t, k);
      const Vec3& A = pts[size_t(f[0])];
      area = std::max(area, norm(cross(sub(pts[size_t(f[1])], A), sub(pts[size_t(f[2])], A))) / 2);
    }
    return area > 0 ? 3 * std::fabs(volume(t)) / area : 0;
  }

  double quality(uint32_t t) const {
    const auto& T = tets[t];
    return tetMinDihedral(pts[size_t(T[0])], pts[size_t(T[1])], pts[size_t(T[2])], pts[size_t(T[3])]);
  }
  double quality(const std::array<int32_t, 4>& T) const {
    return tetMinDihedral(pts[size_t(T[0])], pts[size_t(T[1])], pts[size_t(T[2])], pts[size_t(T[3])]);
  }
  /// Cosine of the minimum dihedral angle of T (tetMaxDihedralCos: 2 when flat or inverted).
  double qualityCos(const std::array<int32_t, 4>& T) const {
    return tetMaxDihedralCos(pts[size_t(T[0])], pts[size_t(T[1])], pts[size_t(T[2])], pts[size_t(T[3])]);
  }
  bool has(uint32_t t, int32_t v) const {
    const auto& T = tets[t];
    return T[0] == v || T[1] == v || T[2] == v || T[3] == v;
  }
  /// Alive tets holding both u and v.
  void tetsOnEdge(int32_t u, int32_t v, std::vector<uint32_t>& out) const {
    out.clear();
    for (uint32_t t : around[size_t(u)])
      if (has(t, v)) out.push_back(t);
  }
  /// The other tet holding face (a, b, c) of tet t, or -1 (outer boundary).
  int64_t across(uint32_t t, int32_t a, int32_t b, int32_t c) const {
    for (uint32_t s : around[size_t(a)])
      if (s != t && has(s, b) && has(s, c)) return int64_t(s);
    return -1;
  }
  /// Face k of tet t (the three vertices other than T[k]).
  std::array<int32_t, 3> face(uint32_t t, int k) const {
    const auto& T = tets[t];
    std::array<int32_t, 3> f;
    int n = 0;
    for (int i = 0; i < 4; ++i)
      if (i != k) f[size_t(n++)] = T[size_t(i)];
    return f;
  }
  /// A vertex is fixed when a constrained face holds it: one on the outer boundary or between two
  /// materials (cached; kill and relabel forget the state of the tet's vertices: peeling and
  /// relabelling may fix a free vertex).
  bool fixedVertex(int32_t v) {
    int8_t& st = fixedState[size_t(v)];
    if (st >= 0) return st == 1;
    st = computeFixed(v, starFaces) ? 1 : 0;
    return st == 1;
  }
  /// fixedVertex's answer, the cache aside (`starFaces`: the caller's scratch), so that several
  /// threads may ask at once.
  bool computeFixed(int32_t v, std::vector<std::array<int32_t, 2>>& starFaces) const {
    if (fixedState[size_t(v)] >= 0) return fixedState[size_t(v)] == 1;
    // The faces holding v, as their two other vertices: each must be held by exactly two of v's
    // tets, of one material (one pass over the star instead of a search per face).
    const auto& star = around[size_t(v)];
    starFaces.clear();
    bool oneMaterial = true;
    for (uint32_t t : star) {
      oneMaterial = oneMaterial && labels[t] == labels[star[0]];
      std::array<int32_t, 3> o{};
      int n = 0;
      for (int32_t w : tets[t])
        if (w != v) o[size_t(n++)] = w;
      std::sort(o.begin(), o.end());
      starFaces.push_back({o[0], o[1]});
      starFaces.push_back({o[0], o[2]});
      starFaces.push_back({o[1], o[2]});
    }
    std::sort(starFaces.begin(), starFaces.end());
    bool paired = oneMaterial && starFaces.size() % 2 == 0;
    for (size_t i = 0; paired && i < starFaces.size(); i += 2)
      paired = starFaces[i] == starFaces[i + 1] &&
               (i + 2 >= starFaces.size() || starFaces[i + 2] != starFaces[i]);
    return !paired;
  }
  void relabel(uint32_t t, int32_t label) {
    for (int32_t v : tets[t]) {
      fixedState[size_t(v)] = -1;
      touch(v);
    }
    --perLabel[size_t(labels[t])];
    labels[t] = label;
    ++perLabel[size_t(label)];
  }
  void kill(uint32_t t) {
    alive[t] = 0;
    --perLabel[size_t(labels[t])];
    for (int32_t v : tets[t]) {
      fixedState[size_t(v)] = -1;
      touch(v);
      auto& a = around[size_t(v)];
      a.erase(std::find(a.begin(), a.end(), t));
    }
  }
  /// Brings back a killed tet (its vertices and label are still in place).
  void revive(uint32_t t) {
    alive[t] = 1;
    ++perLabel[size_t(labels[t])];
    for (int32_t v : tets[t]) {
      fixedState[size_t(v)] = -1;
      touch(v);
      around[size_t(v)].push_back(t);
    }
  }
  /// A new vertex (no tet yet); invalidates references into pts.
  int32_t addPoint(const Vec3& p) {
    pts.push_back(p);
    around.emplace_back();
    fixedState.push_back(-1);
    stamped.push_back(stamp);
    return int32_t(pts.size() - 1);
  }
  uint32_t add(const std::array<int32_t, 4>& T, int32_t label) {
    const uint32_t id = uint32_t(tets.size());
    tets.push_back(T);
    labels.push_back(label);
    alive.push_back(1);
    ++perLabel[size_t(label)];
    for (int32_t v : T) {
      around[size_t(v)].push_back(id);
      touch(v);
    }
    return id;
  }
};

/// A constrained vertex move: `tangent` keeps the allowed part of a displacement, `project` puts
/// a trial position back onto the constraint (false: rejected), `accept` checks the moved star
/// (the vertex already at its trial position; false: rejected). Empty members: no constraint.
struct MoveConstraint {
  std::function<Vec3(const Vec3&)> tangent;
  std::function<bool(Vec3&)> project;
  std::function<bool()> accept;
};

/// Moves vertex v when that raises the worst tet of its star (Laplacian candidate, then line
/// searches along shortestInHull of the gradients of the tets within 0.5 degrees of the worst, or
/// along the worst tet's gradient), within `constraint` when not null. True when moved.
bool smoothVertex(Editor& m, int32_t v, const MoveConstraint* constraint);

/// The point of the convex hull of `g` (not empty) nearest the origin (Gilbert's algorithm): when
/// not zero, a direction in which every g_i rises to first order (g_i . x >= |x|^2 > 0).
Vec3 shortestInHull(const std::vector<Vec3>& g);

/// True when the faces `shell` (each the face of the tet opposite the slot) bound a ball: every
/// edge on exactly two of them and V - E + F = 2. A cavity grown across faces can touch itself
/// along an edge or at a vertex (around a thin rod: a ring of tets closing on itself); joining
/// such a shell to one new vertex would give a triangle shared by three or more tets, so vertex
/// insertion (Optimize.cxx) refuses it.
bool sphereShell(const std::vector<std::pair<std::array<int32_t, 4>, int>>& shell);

/// Edge removal (Optimize.h): re-triangulates the ring of edge (u, v) of tet t, all of t's
/// material, when that raises the ring's worst tet; the new tets go to `fresh`. True when applied.
bool removeEdge(Editor& m, uint32_t t, int32_t u, int32_t v, std::vector<uint32_t>& fresh);

/// 2-to-3 flip across face k of t (the face opposite T[k]) when both tets are of one material
/// and that raises their worst angle; the new tets go to `fresh`. True when applied.
bool flipFace(Editor& m, uint32_t t, int k, std::vector<uint32_t>& fresh);

/// Interface edge flip (InterfaceSmoothing.h) at tet t; the new tets go to `fresh`. True when
/// applied.
bool flipInterfaceEdge(Editor& m, uint32_t t, const OptimizeInterfaces& interfaces,
                       std::vector<uint32_t>& fresh);

/// Relabels a flat tet (thickness at most `tolerance`) to the material that holds more of its
/// faces than its own material does, when the new interface triangles stay within the facet
/// distance and both materials' volume budgets allow; t goes to `fresh`. True when applied.
bool relabelFlatTet(Editor& m, uint32_t t, const OptimizeInterfaces& interfaces, double tolerance,
                    std::vector<uint32_t>& fresh);

/// Edge collapse: an edge of tet t shorter than `maxLength` (mm), shortest first, is collapsed
/// by moving one end (`gone`) onto the other (`keep`), which stays where it is: the tets around
/// the edge vanish and gone's other tets take keep instead. Allowed only when the edge lies on
/// every interface and boundary gone lies on (the same materials around both, an outer face
/// holding the edge if gone is on the outer boundary, every box plane of gone also keep's when
/// `interfaces` knows the box), the link condition holds for the whole mesh
/// and for each material, no new tet is flat or inverted, the worst of the changed tets rises and
/// every material's volume stays within its budget (Editor::moveFits).
/// Interfaces move by at most the edge's length. With `checkFacets` (and interfaces known) every
/// interface triangle around keep must also end within the facet distance of its smooth interface
/// (starWithinFacetDistance), so the edge may be longer than that distance. Both ends are tried
/// as `keep`; the new tets go to `fresh`. True when applied (internal/EdgeCollapse.cxx).
bool collapseEdge(Editor& m, uint32_t t, double maxLength, const OptimizeInterfaces& interfaces,
                  bool checkFacets, std::vector<uint32_t>& fresh);

/// True when every interface triangle around v (outer faces off the volume's box count as the
/// interface with the background) has its centroid within the facet distance of its smooth
/// interface, which must be found there (InterfaceSmoothing.cxx).
bool starWithinFacetDistance(const Editor& m, const OptimizeInterfaces& interfaces, int32_t v);

/// Interior coarsening (OptimizeParameters::coarsenMinDihedral): removes interior vertices by
/// collapsing each onto the neighbour that leaves the best worst tet, shortest edges relative to
/// the target size first, in two sweeps (the second over the neighbours of a removal); the
/// vertices that received a collapse are smoothed after each. Which vertices are interior, and
/// which have short edges, is found on `threads` (as parallelFor; the result does not depend on
/// it). Returns how many vertices went (internal/EdgeCollapse.cxx).
size_t coarsenInterior(Editor& m, const OptimizeParameters& params, int threads);

/// Distance (mm) from the centroid of triangle `f` to the smooth interface of materials a < b
/// (0: the background); -1 when the projection fails (InterfaceSmoothing.cxx).
double faceDistance(const Editor& m, const OptimizeInterfaces& interfaces,
                    const std::array<int32_t, 3>& f, int a, int b);

/// Moves an interface or triple-line vertex along its interface, or a junction point within a
/// quarter of the facet distance (InterfaceSmoothing.h); false when v is interior or on the box,
/// or no move helps. `kind` gets 2 (interface), 3 (triple line) or 4 (junction point).
/// With `offset` > 0 (mm) an interface vertex between two materials may also leave its
/// interface, a triple-line vertex its line (also where the line has no clear direction), to
/// anywhere within `offset` of it (on a plane of the volume's box: within that plane, within
/// `offset` of the interface's trace on it), and a junction point may move within `offset` of
/// where it started: the last resort for a flat tet whose four vertices lie on interfaces (the
/// optimizer's inserting rounds, Optimize.h).
bool smoothInterfaceVertex(Editor& m, int32_t v, const OptimizeInterfaces& interfaces, int& kind,
                           double offset = 0);

/// Moves vertex v by its class: interior vertices freely (smoothVertex), interface and
/// triple-line vertices along their interface (smoothInterfaceVertex, when `interfaces` has one
/// and params.moveInterfaces), vertices of a flat outer-boundary patch within its plane; counts
/// the move in `r`. True when v moved (internal/VertexMoves.cxx).
bool moveVertex(Editor& m, int32_t v, const OptimizeParameters& params,
                const OptimizeInterfaces& interfaces, OptimizeResult& r);

/// The moves of the four vertices of a tet (moveVertex in turn, as the rounds make them) found
/// ahead of time on a copy of their stars (findTetMoves): where each vertex went, the budget
/// questions and bookings on the way (Editor::budgetLog), the junction-point starts recorded and
/// the counts. They are the moves the mesh itself would give while none of the vertices read
/// changed and the budgets answer the same (tetMovesHold).
struct TetMoves {
  bool made = false;
  std::array<bool, 4> moved{};
  std::array<Vec3, 4> to{};
  std::vector<Editor::BudgetEvent> log;
  std::array<bool, 4> junctionStarted{};
  std::array<Vec3, 4> junctionStart{};
  std::array<int8_t, 4> fixedState{};  // Editor::fixedState of the four vertices found on the way
  OptimizeResult counts;
};

/// Finds the moves of tet t's vertices (TetMoves) without changing `m`: the tets around the four
/// vertices (their whole stars) are copied with their vertices, each copied vertex keeping its
/// copied tets in the order the mesh holds them (so every search visits them as on the mesh),
/// and the vertices move on the copy. Safe on several threads at once while nothing edits `m`.
void findTetMoves(const Editor& m, uint32_t t, const OptimizeParameters& params,
                  const OptimizeInterfaces& interfaces, TetMoves& out);

/// True when the moves found for tet t are still the ones the mesh gives: no vertex of the four
/// stars changed since they were found (Editor::stamp) and the budgets answer the same.
bool tetMovesHold(const Editor& m, uint32_t t, const TetMoves& found);

/// Makes the moves found for tet t (tetMovesHold): the tets around the vertices that moved go to
/// `fresh`. True when a vertex moved.
bool applyTetMoves(Editor& m, uint32_t t, const TetMoves& found, OptimizeResult& r,
                   std::vector<uint32_t>& fresh);

/// Removes a flat tet with a face on the outer boundary (peeling, see Optimize.h; in
/// internal/Fragments.cxx); the tets across its other faces (now on the outer boundary) go to
/// `fresh`. The specks it cuts off (specksCutOff) go with it, and their volume counts in the
/// peeling budget of their materials; `overBudget`: even beyond that budget (the last resort).
bool peel(Editor& m, uint32_t t, const OptimizeParameters& params, double share,
          const OptimizeInterfaces& in, std::vector<uint32_t>& fresh, bool overBudget = false);

/// The pieces of the mesh that removing tet t would cut off (connected to the rest through t's
/// faces only) and that the last step would remove as specks (removeFragments' rule: lighter than
/// `minVolume` mm^3, or than `badMinVolume` with a tet below `target` degrees), into `specks`
/// (their tets). Each piece is searched from a tet across one of t's faces (nb) until it is too
/// heavy to be one.
void specksCutOff(const Editor& m, uint32_t t, const int64_t nb[4], double minVolume,
                  double badMinVolume, double target, std::vector<uint32_t>& specks);

/// A floating piece with a tet below the target angle goes when lighter than this many times
/// the fragment limit (OptimizeParameters::minFragmentVoxels).
constexpr double kBadFragmentFactor = 10;

/// Removes the face-connected pieces of the mesh (over all materials) lighter than `minVolume`
/// mm^3, or lighter than `badMinVolume` when one of their tets is below `target` degrees (a
/// floating piece no operation could mend: every face of it is outer), except a piece holding a
/// material's last tets (and the points only they used); counts them in `r`. The search for the
/// pieces runs on `threads` (as parallelFor); the result does not depend on it
/// (internal/Fragments.cxx).
void removeFragments(std::vector<Vec3>& points, std::vector<std::array<int32_t, 4>>& tets,
                     std::vector<int32_t>& labels, double minVolume, double badMinVolume,
                     double target, int threads, OptimizeResult& r);

}  // namespace optimize_detail
}  // namespace femesher
