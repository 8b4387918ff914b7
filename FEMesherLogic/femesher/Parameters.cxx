// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/Parameters.h>
#include <femesher/Spelling.h>
#include <femesher/io/ContactSplit.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <set>
#include <sstream>

namespace femesher {

namespace {

using json = nlohmann::json;

struct Binding {
  ParameterDescriptor desc;
  std::function<void(MeshingParameters&, double)> set;
  std::function<double(const MeshingParameters&)> get;
};

std::string trimmed(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r\n");
  if (b == std::string::npos) return {};
  return s.substr(b, s.find_last_not_of(" \t\r\n") - b + 1);
}

std::string fmt(double v) {
  std::ostringstream os;
  os.precision(10);
  os << v;
  return os.str();
}

const std::vector<Binding>& bindings() {
  static const std::vector<Binding> b = [] {
    std::vector<Binding> v;
    auto add = [&](ParameterDescriptor d, std::function<void(MeshingParameters&, double)> s,
                   std::function<double(const MeshingParameters&)> g) {
      d.defaultValue = fmt(g(MeshingParameters{}));
      v.push_back({std::move(d), std::move(s), std::move(g)});
    };
    add({"min_voxels", "int", "voxels", "", 1, 1e6, "Smallest label kept",
         "Labels with fewer voxels are dropped (their voxels join the most common neighbouring "
         "label) with a warning naming them; every other label appears in the mesh.", false},
        [](MeshingParameters& p, double x) { p.preprocess.minVoxels = int64_t(x); },
        [](const MeshingParameters& p) { return double(p.preprocess.minVoxels); });
    add({"smoothing_sigma", "double", "voxels", "", 0, 3, "Surface smoothing",
         "Gaussian smoothing of each material's signed distance, in voxels. 0 = the trilinear "
         "signed distance (sub-voxel already); 0.5-1 rounds the staircase more but shrinks thin "
         "and small labels (surfaces never pass a voxel centre).",
         true},
        [](MeshingParameters& p, double x) { p.indicators.sigma = x; },
        [](const MeshingParameters& p) { return p.indicators.sigma; });
    add({"volume_correction", "int", "", "", 0, 10, "Volume-preserving surfaces",
         "Rounds of the volume-preserving correction of the smooth surfaces: the volume the "
         "rounding of voxel corners and edges takes from a label is given back on the faces next to "
         "them (small labels otherwise lose about a tenth of their volume). 0 = off.", true},
        [](MeshingParameters& p, double x) { p.indicators.volumeIterations = int(x); },
        [](const MeshingParameters& p) { return double(p.indicators.volumeIterations); });
    add({"target_edge_length", "double", "mm", "", 0, 1e6, "Element size",
         "Target edge length of the surface triangles in mm. Smaller = finer mesh. 0 = automatic "
         "(edge_length_factor x the mean voxel spacing).", false},
        [](MeshingParameters& p, double x) { p.sizing.targetEdgeLength = x; },
        [](const MeshingParameters& p) { return p.sizing.targetEdgeLength; });
    add({"edge_length_factor", "double", "voxels", "", 0.5, 50, "Element size (voxels)",
         "Automatic element size as a multiple of the mean voxel spacing, used when "
         "target_edge_length is 0.", false},
        [](MeshingParameters& p, double x) { p.sizing.edgeLengthFactor = x; },
        [](const MeshingParameters& p) { return p.sizing.edgeLengthFactor; });
    add({"sizing_scale", "double", "", "", 0.05, 5, "Detail (sizing scale)",
         "Adaptive sizing: target edge length = sizing_scale x local feature size (distance to the "
         "nearest medial axis). Smaller = more detail in thin and curved parts.", false},
        [](MeshingParameters& p, double x) { p.sizing.scale = x; },
        [](const MeshingParameters& p) { return p.sizing.scale; });
    add({"curvature_distance", "double", "voxels", "", 0, 10, "Curvature sizing",
         "Adaptive sizing: where an interface bends, the edge length is lowered until a "
         "triangle's centroid lies within this distance of the smooth interface (the curvature "
         "is probed with chords of the candidate length). 0 = sizes from the local feature size "
         "alone.", true},
        [](MeshingParameters& p, double x) { p.sizing.curvatureDistance = x; },
        [](const MeshingParameters& p) { return p.sizing.curvatureDistance; });
    add({"h_min", "double", "mm", "", 0, 1e6, "Smallest element",
         "Adaptive sizing: lower bound of the edge length in mm (0 = half the uniform edge length).",
         true},
        [](MeshingParameters& p, double x) { p.sizing.hMin = x; },
        [](const MeshingParameters& p) { return p.sizing.hMin; });
    add({"h_max", "double", "mm", "", 0, 1e6, "Largest element",
         "Adaptive sizing: upper bound of the edge length in mm (0 = edge_length_factor x 2.5 x "
         "the mean voxel spacing).", true},
        [](MeshingParameters& p, double x) { p.sizing.hMax = x; },
        [](const MeshingParameters& p) { return p.sizing.hMax; });
    add({"gradation", "double", "", "", 0.01, 10, "Size gradation",
         "Adaptive sizing: the edge length grows at most this many mm per mm away from fine parts.",
         true},
        [](MeshingParameters& p, double x) { p.sizing.gradation = x; },
        [](const MeshingParameters& p) { return p.sizing.gradation; });
    add({"volume_sizing", "bool", "", "", 0, 1, "Size the interior too",
         "Adaptive sizing: hand the sizing field to TetGen (-m) so the interior follows it too "
         "(more tets); off: the interior is graded from the surface by TetGen's quality bound.",
         true},
        [](MeshingParameters& p, double x) { p.sizing.volumeSizing = x != 0; },
        [](const MeshingParameters& p) { return p.sizing.volumeSizing ? 1.0 : 0.0; });
    add({"particle_iterations", "int", "", "", 0, 1000, "Particle iterations",
         "Maximum iterations of the surface particle system (it stops earlier when converged); "
         "0 uses the initial samples as they are.", true},
        [](MeshingParameters& p, double x) { p.particles.maxIterations = int(x); },
        [](const MeshingParameters& p) { return double(p.particles.maxIterations); });
    add({"facet_distance", "double", "voxels", "", 0, 10, "Surface accuracy",
         "Largest distance, in voxels, between an interface triangle's centroid and the smooth "
         "interface; triangles farther off get a point inserted on the interface (surface "
         "refinement after the particle system). Smaller = thin and curved parts follow the labels "
         "more closely, at more elements. 0 = no refinement.", true},
        [](MeshingParameters& p, double x) { p.boundary.facetDistance = x; },
        [](const MeshingParameters& p) { return p.boundary.facetDistance; });
    add({"facet_angle", "double", "degrees", "", 0, 30, "Needle triangles",
         "Interface triangles with an angle below this whose longest edge is longer than 1.5 x the "
         "target size get a point where their dual Voronoi edge crosses the interface (CGAL's "
         "facet_angle, limited to large triangles; after facet_distance). Helps thin plates and "
         "small shapes sampled coarsely (a one-voxel plate: worst tet 3.5 -> 15 degrees); on the "
         "shared label maps it moves the worst tet either way. 0 = off.", true},
        [](MeshingParameters& p, double x) { p.boundary.facetShape.minAngleDegrees = x; },
        [](const MeshingParameters& p) { return p.boundary.facetShape.minAngleDegrees; });
    add({"voxel_refinement", "bool", "", "", 0, 1, "Voxel-exact surfaces",
         "Insert interface points until every voxel centre next to another label lies in a tet of "
         "its own label (the mesh reproduces the label map at the voxel centres: voxel_centre_dice "
         "close to 1; it buys little volume Dice on thin layers). Off: fewer surface points, "
         "fidelity set by facet_distance alone.", true},
        [](MeshingParameters& p, double x) { p.boundary.voxelRefinement = x != 0; },
        [](const MeshingParameters& p) { return p.boundary.voxelRefinement ? 1.0 : 0.0; });
    add({"max_radius_edge_ratio", "double", "", "", 0, 10, "Quality bound (radius-edge)",
         "TetGen's bound on the circumradius / shortest edge of each tet (-q). 0 disables quality "
         "refinement. Values below about 1.2 may not terminate.", true},
        [](MeshingParameters& p, double x) { p.volume.maxRadiusEdgeRatio = x; },
        [](const MeshingParameters& p) { return p.volume.maxRadiusEdgeRatio; });
    add({"min_dihedral_angle", "double", "degrees", "", 0, 18, "Quality bound (min dihedral)",
         "TetGen's minimum dihedral angle target in degrees (-q ratio/angle). Low on purpose: "
         "TetGen fixes flat tets by adding interior points, the Optimize stage by flips, moves "
         "and splits; 12 gives 11-26 % more tets for the same worst angle after Optimize. Above "
         "about 18 TetGen may not terminate.", true},
        [](MeshingParameters& p, double x) { p.volume.minDihedralAngle = x; },
        [](const MeshingParameters& p) { return p.volume.minDihedralAngle; });
    add({"max_tet_volume", "double", "mm^3", "", 0, 1e9, "Largest element volume",
         "Upper bound on the volume of any tet in mm^3 (TetGen -a). 0 = no bound.", true},
        [](MeshingParameters& p, double x) { p.volume.maxTetVolume = x; },
        [](const MeshingParameters& p) { return p.volume.maxTetVolume; });
    add({"preserve_interfaces", "bool", "", "", 0, 1, "Keep interface triangles",
         "Keep the interface triangles exactly as sampled (TetGen -Y). When TetGen cannot, the run "
         "falls back to splitting them and says so.", true},
        [](MeshingParameters& p, double x) { p.volume.preserveInterfaces = x != 0; },
        [](const MeshingParameters& p) { return p.volume.preserveInterfaces ? 1.0 : 0.0; });
    add({"optimization_level", "int", "", "", 0, 10, "Optimisation effort",
         "TetGen mesh optimisation level (-O): flips and smoothing against slivers.", true},
        [](MeshingParameters& p, double x) { p.volume.optimizationLevel = int(x); },
        [](const MeshingParameters& p) { return double(p.volume.optimizationLevel); });
    add({"volume_per_material", "bool", "", "", 0, 1, "Mesh materials in parallel",
         "With preserve_interfaces: TetGen meshes each material on its own, several at a time (one "
         "per thread); the pieces share the unsplit interface triangles. Off: one TetGen run for "
         "the whole surface.", true},
        [](MeshingParameters& p, double x) { p.volume.perMaterial = x != 0; },
        [](const MeshingParameters& p) { return p.volume.perMaterial ? 1.0 : 0.0; });
    add({"optimize_min_dihedral", "double", "degrees", "", 0, 40, "Sliver removal target",
         "After TetGen, tets whose smallest dihedral angle is below this are improved by edge and "
         "face flips inside one material, vertex smoothing (interface vertices along their smooth "
         "interface, see optimize_interfaces) and peeling of flat boundary tets. 0 = off.", true},
        [](MeshingParameters& p, double x) { p.optimize.targetMinDihedral = x; },
        [](const MeshingParameters& p) { return p.optimize.targetMinDihedral; });
    add({"sliver_peel_distance", "double", "voxels", "", 0, 1, "Boundary sliver peeling",
         "A flat tet with a face on the mesh's outer boundary (background or volume box) is "
         "removed when it is thinner than this (voxels of the smallest spacing; at most 0.4 % of "
         "a material's volume in all): the outer surface moves by at most that much. A flat tet "
         "between materials that is this thin (or thinner than facet_distance) joins the material "
         "holding most of its faces. "
         "A thicker tet with a face on the outer boundary (not the volume box) is removed too when "
         "the faces it uncovers lie within facet_distance of the smooth boundary. 0 = never.", true},
        [](MeshingParameters& p, double x) { p.optimize.peelDistance = x; },
        [](const MeshingParameters& p) { return p.optimize.peelDistance; });
    add({"optimize_vertex_insertion", "bool", "", "", 0, 1, "Vertex insertion",
         "When no flip, move, peel or relabelling helps a tet below optimize_min_dihedral, a "
         "vertex is inserted in it and its neighbours of the same material and placed where the "
         "worst new tet is best (kept only when that beats the old worst). Interfaces and the outer "
         "boundary do not change. Off: no vertex is added (no edge split either).", true},
        [](MeshingParameters& p, double x) { p.optimize.insertVertices = x != 0; },
        [](const MeshingParameters& p) { return p.optimize.insertVertices ? 1.0 : 0.0; });
    add({"optimize_edge_split", "bool", "", "", 0, 1, "Edge split",
         "With optimize_vertex_insertion, when inserting a vertex does not help a tet either, its "
         "longest edge that helps is split at the midpoint together with every tet around it (any "
         "material, so the mesh stays conformal), and the new vertex moves along its interface, "
         "triple line or flat outer patch (within facet_distance, as optimize_interfaces moves "
         "do), or freely inside a material; kept only when the worst tet around the edge rises. "
         "Off: no edge is split.", true},
        [](MeshingParameters& p, double x) { p.optimize.splitEdges = x != 0; },
        [](const MeshingParameters& p) { return p.optimize.splitEdges ? 1.0 : 0.0; });
    add({"optimize_edge_collapse", "bool", "", "", 0, 1, "Short edge collapse",
         "An edge of a tet below optimize_min_dihedral shorter than facet_distance (two "
         "junction or interface vertices almost on top of each other) is collapsed onto one of its "
         "ends when the edge lies on every interface that end lies on and the topology of the mesh "
         "and of each material stays the same; where nothing else helps, also an edge up to "
         "eight facet_distances long, when every interface triangle left around the kept end "
         "lies within facet_distance of its smooth interface. Off: no vertex is removed.", true},
        [](MeshingParameters& p, double x) { p.optimize.collapseEdges = x != 0; },
        [](const MeshingParameters& p) { return p.optimize.collapseEdges ? 1.0 : 0.0; });
    add({"optimize_coarsen_min_dihedral", "double", "degrees", "", 0, 40, "Interior coarsening",
         "After the sliver removal, interior vertices (inside one material, on no interface or "
         "outer face) with an edge shorter than 1.3 x the target size there are removed, each "
         "collapsed onto the neighbour that leaves the best tets, when no new edge is longer than "
         "3 x the target size and every new tet's smallest dihedral angle is at least this (or at "
         "least the worst tet it replaces, so the worst angle never drops). Fewer tets in thick "
         "parts. Interfaces, the outer boundary and every material's volume do not change. 0 = off.", true},
        [](MeshingParameters& p, double x) { p.optimize.coarsenMinDihedral = x; },
        [](const MeshingParameters& p) { return p.optimize.coarsenMinDihedral; });
    add({"min_fragment_voxels", "double", "voxels", "", 0, 1000, "Floating fragment removal",
         "After optimisation, pieces of the mesh connected to the rest by no face (floating "
         "elements: each is a rigid-body mode for a solver) with less volume than this many "
         "voxels are removed (up to ten times this volume when a tet of the piece is below "
         "optimize_min_dihedral: no operation can mend it), unless a material would vanish; the "
         "report counts them. 0 = keep them.", true},
        [](MeshingParameters& p, double x) { p.optimize.minFragmentVoxels = x; },
        [](const MeshingParameters& p) { return p.optimize.minFragmentVoxels; });
    add({"optimize_interfaces", "bool", "", "", 0, 1, "Move interface vertices",
         "The optimizer also moves vertices on an interface between two materials (along it) and "
         "on triple lines (along the line), keeping every interface triangle within "
         "facet_distance of the smooth interface; both sides move together, so the mesh stays "
         "conformal. Off: interface vertices stay where TetGen left them.", true},
        [](MeshingParameters& p, double x) { p.optimize.moveInterfaces = x != 0; },
        [](const MeshingParameters& p) { return p.optimize.moveInterfaces ? 1.0 : 0.0; });
    add({"min_dihedral_warning", "double", "degrees", "", 0, 90, "Poor element warning",
         "After optimisation, tets whose smallest dihedral angle is below this are counted and "
         "the worst listed in the report, the run warns and its status is poor_elements instead "
         "of ok. 0 = no warning.", true},
        [](MeshingParameters& p, double x) { p.optimize.minDihedralWarning = x; },
        [](const MeshingParameters& p) { return p.optimize.minDihedralWarning; });
    add({"threads", "int", "", "", 0, 1024, "Threads", "Worker threads; 0 = all cores.", true},
        [](MeshingParameters& p, double x) { p.run.threads = int(x); },
        [](const MeshingParameters& p) { return double(p.run.threads); });
    add({"seed", "int", "", "", 0, 4294967295.0, "Random seed",
         "Seed of the sampling order; the same seed and thread count give the same mesh.", true},
        [](MeshingParameters& p, double x) { p.run.seed = uint64_t(x); },
        [](const MeshingParameters& p) { return double(p.run.seed); });
    add({"compute_fidelity", "bool", "", "", 0, 1, "Fidelity report",
         "Compare the mesh with the input labels (Dice, volume error, boundary distance).", true},
        [](MeshingParameters& p, double x) { p.run.computeFidelity = x != 0; },
        [](const MeshingParameters& p) { return p.run.computeFidelity ? 1.0 : 0.0; });
    add({"default.E", "double", "MPa", "", 1e-12, 1e9, "Young's modulus (default)",
         "Young's modulus written for every material in solver exports unless overridden with "
         "material.<label>.E.", true},
        [](MeshingParameters& p, double x) { p.defaultMaterial.youngsModulus = x; },
        [](const MeshingParameters& p) { return p.defaultMaterial.youngsModulus; });
    add({"default.nu", "double", "", "", -0.999, 0.4999, "Poisson ratio (default)",
         "Poisson ratio written for every material unless overridden with material.<label>.nu.",
         true},
        [](MeshingParameters& p, double x) { p.defaultMaterial.poissonRatio = x; },
        [](const MeshingParameters& p) { return p.defaultMaterial.poissonRatio; });
    add({"default.density", "double", "t/mm^3", "", 0, 1e3, "Density (default)",
         "Mass density written for every material in solver exports.", true},
        [](MeshingParameters& p, double x) { p.defaultMaterial.density = x; },
        [](const MeshingParameters& p) { return p.defaultMaterial.density; });
    add({"element_order", "int", "", "", 1, 2, "Element order",
         "1: 4-node tets (C3D4, tet4). 2: 10-node tets (C3D10 in .inp, Gmsh type 11 in .msh, "
         "VTK quadratic tetra in .vtu/.vtk, tet10 in .feb), one mid-edge node per edge, shared "
         "across materials: on interfaces and the outer boundary curved onto the smooth surface "
         "where every element stays valid, elsewhere at the straight edge midpoint. .mesh and "
         ".stl cannot hold them.", true},
        [](MeshingParameters& p, double x) { p.elementOrder = int(x); },
        [](const MeshingParameters& p) { return double(p.elementOrder); });
    return v;
  }();
  return b;
}

ParameterDescriptor sizingDescriptor() {
  ParameterDescriptor d;
  d.key = "sizing";
  d.type = "choice";
  d.defaultValue = sizingModeName(SizingParameters{}.mode);
  d.label = "Sizing";
  d.help = "'adaptive': element size follows the local feature size from the Integer Medial Axis "
           "(small in thin and curved parts, large where the shape is simple); 'uniform': one "
           "size (target_edge_length or edge_length_factor) everywhere.";
  d.choices = {"adaptive", "uniform"};
  return d;
}

ParameterDescriptor surfaceMesherDescriptor() {
  ParameterDescriptor d;
  d.key = "surface_mesher";
  d.type = "choice";
  d.defaultValue = surfaceMesherName(BoundaryMeshParameters{}.mesher);
  d.label = "Surface mesher";
  d.help = "How the interface triangles are made from the particles: 'delaunay' (restricted "
           "Delaunay, watertight by construction) or 'ldt' (local Delaunay triangulation in each "
           "particle's tangent plane with natural-neighbour 1-rings; holes are counted and filled).";
  d.advanced = true;
  d.choices = {"delaunay", "ldt"};
  return d;
}

ParameterDescriptor contactPairsDescriptor() {
  ParameterDescriptor d;
  d.key = "contact_pairs";
  d.type = "string";
  d.label = "Contact pairs";
  d.help = "Material pairs whose interface becomes two coincident surfaces with their own nodes, "
           "written as a contact pair in .inp (*CONTACT PAIR) and .feb (sliding-elastic contact): "
           "label pairs A:B separated by commas, e.g. 2:4,6:5 (A is the dependent side). Empty: "
           "every interface stays tied.";
  d.advanced = true;
  return d;
}

const Binding* findBinding(const std::string& key) {
  for (const auto& b : bindings())
    if (b.desc.key == key) return &b;
  return nullptr;
}

bool parseNumber(const std::string& text, const std::string& type, double& out) {
  if (type == "bool") {
    bool b = false;
    if (!parseBoolean(text, b)) return false;
    out = b ? 1 : 0;
    return true;
  }
  if (text.empty()) return false;
  char* end = nullptr;
  errno = 0;
  out = std::strtod(text.c_str(), &end);
  if (errno != 0 || end == text.c_str() || *end != '\0' || !std::isfinite(out)) return false;
  if (type == "int" && out != std::floor(out)) return false;
  return true;
}

Status setMaterialParameter(MeshingParameters& params, const std::string& key,
                            const std::string& value) {
  // material.<label>.<E|nu|density|exclude|name>
  const auto dot = key.find('.', 9);
  if (dot == std::string::npos)
    return {ErrorCode::InvalidArgument,
            "Parameter '" + key + "': use material.<label>.E, material.<label>.nu, "
            "material.<label>.density, material.<label>.name or material.<label>.exclude"};
  const std::string labelText = key.substr(9, dot - 9), field = key.substr(dot + 1);
  double label = 0, x = 0;
  if (!parseNumber(labelText, "int", label))
    return {ErrorCode::InvalidArgument, "Parameter '" + key + "': '" + labelText +
                                            "' is not an integer label id"};
  if (field == "name") {
    const std::string name = trimmed(value);
    if (name.empty())
      return {ErrorCode::InvalidArgument,
              "Parameter '" + key + "': the name is empty; give the material a name, e.g. --set " +
                  key + "=\"femoral cartilage\""};
    if (std::any_of(name.begin(), name.end(),
                    [](char c) { return static_cast<unsigned char>(c) < 0x20 || c == 0x7f; }))
      return {ErrorCode::InvalidArgument,
              "Parameter '" + key + "': the name holds a control character (a line break or a "
              "tab); give it on one line"};
    params.preprocess.names[int32_t(label)] = name;
    return Status::ok();
  }
  if (field == "exclude") {
    if (value == "no" || value == "false") {
      params.preprocess.excluded.erase(int32_t(label));
    } else if (value == "background") {
      params.preprocess.excluded[int32_t(label)] = Exclusion::Background;
    } else if (value == "merge") {
      params.preprocess.excluded[int32_t(label)] = Exclusion::MergeIntoNeighbour;
    } else {
      return {ErrorCode::InvalidArgument,
              "Parameter '" + key + "' = '" + value +
                  "': use 'background' (the material's voxels become background), 'merge' (they "
                  "join the neighbouring material) or 'no'"};
    }
    return Status::ok();
  }
  if (field != "E" && field != "nu" && field != "density")
    return {ErrorCode::InvalidArgument,
            "Parameter '" + key + "': unknown material field '" + field + "'." +
                didYouMean(field, {"E", "nu", "density", "name", "exclude"}) +
                " Use E, nu, density, name or exclude."};
  if (!parseNumber(value, "double", x))
    return {ErrorCode::InvalidArgument, "Parameter '" + key + "': '" + value + "' is not a number"};
  auto it = params.materialProperties.find(int32_t(label));
  ElasticProperties props = it != params.materialProperties.end() ? it->second
                                                                  : params.defaultMaterial;
  if (field == "E") {
    if (x <= 0) return {ErrorCode::InvalidArgument, "Parameter '" + key + "' must be > 0 (MPa)"};
    props.youngsModulus = x;
  } else if (field == "nu") {
    if (x <= -1 || x >= 0.5)
      return {ErrorCode::InvalidArgument, "Parameter '" + key + "' must be in (-1, 0.5)"};
    props.poissonRatio = x;
  } else {  // density
    if (x < 0) return {ErrorCode::InvalidArgument, "Parameter '" + key + "' must be >= 0"};
    props.density = x;
  }
  params.materialProperties[int32_t(label)] = props;
  return Status::ok();
}

}  // namespace

bool parseBoolean(const std::string& text, bool& value) {
  if (text == "true" || text == "on" || text == "yes" || text == "1") {
    value = true;
    return true;
  }
  if (text == "false" || text == "off" || text == "no" || text == "0") {
    value = false;
    return true;
  }
  return false;
}

std::string sizingModeName(SizingMode m) { return m == SizingMode::Adaptive ? "adaptive" : "uniform"; }

std::string surfaceMesherName(SurfaceMesher m) {
  return m == SurfaceMesher::LocalDelaunay ? "ldt" : "delaunay";
}

std::string exclusionName(Exclusion e) {
  return e == Exclusion::Background ? "background" : "merge";
}

const std::vector<ParameterDescriptor>& parameterDescriptors() {
  static const std::vector<ParameterDescriptor> d = [] {
    std::vector<ParameterDescriptor> v;
    for (const auto& b : bindings()) v.push_back(b.desc);
    v.push_back(sizingDescriptor());
    v.push_back(surfaceMesherDescriptor());
    v.push_back(contactPairsDescriptor());
    return v;
  }();
  return d;
}

Status setParameter(MeshingParameters& params, const std::string& key, const std::string& value) {
  if (key.rfind("material.", 0) == 0) return setMaterialParameter(params, key, value);
  if (key == "sizing") {
    if (value != "adaptive" && value != "uniform")
      return {ErrorCode::InvalidArgument,
              "Parameter 'sizing' = '" + value + "': use 'adaptive' or 'uniform'"};
    params.sizing.mode = value == "adaptive" ? SizingMode::Adaptive : SizingMode::Uniform;
    return Status::ok();
  }
  if (key == "surface_mesher") {
    if (value != "delaunay" && value != "ldt")
      return {ErrorCode::InvalidArgument,
              "Parameter 'surface_mesher' = '" + value + "': use 'delaunay' or 'ldt'"};
    params.boundary.mesher =
        value == "ldt" ? SurfaceMesher::LocalDelaunay : SurfaceMesher::RestrictedDelaunay;
    return Status::ok();
  }
  if (key == "contact_pairs") {
    try {
      params.contactPairs = parseContactPairs(value);
    } catch (const Error& e) {
      return e.status();
    }
    return Status::ok();
  }
  const Binding* b = findBinding(key);
  if (!b) {
    std::string known;
    std::vector<std::string> keys = {"sizing", "surface_mesher", "contact_pairs"};
    for (const auto& x : bindings()) {
      known += (known.empty() ? "" : ", ") + x.desc.key;
      keys.push_back(x.desc.key);
    }
    // "materal.1.E": offer the material key with the same label and field.
    if (const auto dot = key.find('.'); dot != std::string::npos)
      keys.push_back("material" + key.substr(dot));
    return {ErrorCode::InvalidArgument,
            "Unknown parameter '" + key + "'." + didYouMean(key, keys) + " Known parameters: " +
                known + ", contact_pairs, material.<label>.E|nu|density|name|exclude."};
  }
  double x = 0;
  if (!parseNumber(value, b->desc.type, x))
    return {ErrorCode::InvalidArgument, "Parameter '" + key + "': '" + value + "' is not a valid " +
                                            b->desc.type + " value"};
  if (x < b->desc.minimum || x > b->desc.maximum)
    return {ErrorCode::InvalidArgument, "Parameter '" + key + "' = " + value +
                                            " is out of range [" + fmt(b->desc.minimum) + ", " +
                                            fmt(b->desc.maximum) + "] " + b->desc.unit};
  b->set(params, x);
  return Status::ok();
}

std::string getParameter(const MeshingParameters& params, const std::string& key) {
  if (key == "surface_mesher") return surfaceMesherName(params.boundary.mesher);
  if (key == "sizing") return sizingModeName(params.sizing.mode);
  if (key == "contact_pairs") return contactPairsText(params.contactPairs);
  const Binding* b = findBinding(key);
  if (!b) return {};
  const double v = b->get(params);
  if (b->desc.type == "bool") return v != 0 ? "true" : "false";
  return fmt(v);
}

std::vector<std::string> presetNames() { return {"coarse", "default", "fine"}; }

Result<MeshingParameters> presetParameters(const std::string& name) {
  MeshingParameters p;
  if (name == "default") return p;
  // Each preset aims at a boundary accuracy (the README's preset table gives what they reach on
  // the knee; measured there, coarse to fine span 4x in tets).
  if (name == "coarse") {  // boundary within about one voxel: no voxel-centre pass
    p.sizing.edgeLengthFactor = 6.0;
    p.boundary.facetDistance = 0.75;
    p.boundary.voxelRefinement = false;
    return p;
  }
  if (name == "fine") {  // boundary within about a third of a voxel
    p.sizing.edgeLengthFactor = 1.5;
    p.boundary.facetDistance = 0.3;
    return p;
  }
  return Result<MeshingParameters>(ErrorCode::InvalidArgument,
                                   "Unknown preset '" + name + "' (coarse, default, fine)");
}

std::string parametersToJson(const MeshingParameters& params) {
  json j;
  for (const auto& b : bindings()) {
    const double v = b.get(params);
    if (b.desc.type == "bool") j[b.desc.key] = v != 0;
    else if (b.desc.type == "int") j[b.desc.key] = int64_t(v);
    else j[b.desc.key] = v;
  }
  j["surface_mesher"] = surfaceMesherName(params.boundary.mesher);
  j["sizing"] = sizingModeName(params.sizing.mode);
  j["contact_pairs"] = contactPairsText(params.contactPairs);
  json mats = json::object();
  for (const auto& [label, m] : params.materialProperties)
    mats[std::to_string(label)] = {{"E", m.youngsModulus}, {"nu", m.poissonRatio},
                                   {"density", m.density}};
  for (const auto& [label, how] : params.preprocess.excluded)
    mats[std::to_string(label)]["exclude"] = exclusionName(how);
  for (const auto& [label, name] : params.preprocess.names) mats[std::to_string(label)]["name"] = name;
  j["materials"] = mats;
  return j.dump(2);
}

std::string parameterDescriptorsToJson() {
  json list = json::array();
  for (const auto& d : parameterDescriptors()) {
    json j = {{"key", d.key},     {"type", d.type},   {"unit", d.unit},
              {"label", d.label}, {"help", d.help},   {"advanced", d.advanced}};
    const Binding* b = findBinding(d.key);
    if (b) {
      const double v = b->get(MeshingParameters{});
      if (d.type == "bool") j["default"] = v != 0;
      else if (d.type == "int") j["default"] = int64_t(v);
      else j["default"] = v;
      if (d.type == "int") {
        j["minimum"] = int64_t(d.minimum);
        j["maximum"] = int64_t(d.maximum);
      } else if (d.type == "double") {
        j["minimum"] = d.minimum;
        j["maximum"] = d.maximum;
      }
    } else {
      j["default"] = d.defaultValue;
      if (d.type == "choice") j["choices"] = d.choices;
    }
    list.push_back(j);
  }
  return list.dump(2);
}

Result<MeshingParameters> parametersFromJson(const std::string& text,
                                             const MeshingParameters& base) {
  json j;
  try {
    j = json::parse(text);
  } catch (const std::exception& e) {
    return Result<MeshingParameters>(ErrorCode::InvalidArgument,
                                     std::string("Parameter file is not valid JSON: ") + e.what());
  }
  if (!j.is_object())
    return Result<MeshingParameters>(ErrorCode::InvalidArgument,
                                     "Parameter file must hold a JSON object of key: value");
  MeshingParameters p = base;
  for (auto it = j.begin(); it != j.end(); ++it) {
    if (it.key() == "materials") {
      if (!it->is_object())
        return Result<MeshingParameters>(ErrorCode::InvalidArgument,
                                         "\"materials\" must be an object label -> {E, nu, density, name, exclude}");
      for (auto m = it->begin(); m != it->end(); ++m) {
        for (auto f = m->begin(); f != m->end(); ++f) {
          if (f.key() == "exclude" || f.key() == "name") {
            if (!f->is_string())
              return Result<MeshingParameters>(ErrorCode::InvalidArgument,
                                               "materials." + m.key() + "." + f.key() +
                                                   " must be a string");
            Status s = setParameter(p, "material." + m.key() + "." + f.key(), f->get<std::string>());
            if (!s) return s;
            continue;
          }
          if (!f->is_number())
            return Result<MeshingParameters>(ErrorCode::InvalidArgument,
                                             "materials." + m.key() + "." + f.key() +
                                                 " must be a number");
          Status s = setParameter(p, "material." + m.key() + "." + f.key(),
                                  fmt(f->get<double>()));
          if (!s) return s;
        }
      }
      continue;
    }
    std::string value;
    if (it->is_boolean()) value = it->get<bool>() ? "true" : "false";
    else if (it->is_number_integer()) value = std::to_string(it->get<int64_t>());
    else if (it->is_number()) value = fmt(it->get<double>());
    else if (it->is_string()) value = it->get<std::string>();
    else
      return Result<MeshingParameters>(ErrorCode::InvalidArgument,
                                       "Parameter '" + it.key() + "' has an unsupported value");
    Status s = setParameter(p, it.key(), value);
    if (!s) return s;
  }
  return p;
}

Result<MeshingParameters> loadParametersFile(const std::string& path,
                                             const MeshingParameters& base) {
  std::ifstream in(path);
  if (!in)
    return Result<MeshingParameters>(ErrorCode::FileNotFound,
                                     "Cannot open parameter file '" + path + "'");
  std::stringstream ss;
  ss << in.rdbuf();
  auto r = parametersFromJson(ss.str(), base);
  if (!r) return Status(r.status().code(), path + ": " + r.status().message());
  return r;
}

Status checkMaterialLabels(const MeshingParameters& params, const std::vector<int32_t>& labels,
                           const std::string& source) {
  std::set<int32_t> given;
  for (const auto& kv : params.materialProperties) given.insert(kv.first);
  for (const auto& kv : params.preprocess.names) given.insert(kv.first);
  const std::set<int32_t> present(labels.begin(), labels.end());
  std::vector<int32_t> unknown;
  for (int32_t l : given)
    if (!present.count(l)) unknown.push_back(l);
  if (unknown.empty()) return Status::ok();
  auto list = [](const auto& v) {
    std::string t;
    for (int32_t l : v) t += (t.empty() ? "" : ", ") + std::to_string(l);
    return t;
  };
  const std::string what = source.empty() ? std::string("The label map") : "'" + source + "'";
  std::string keys;
  for (int32_t l : unknown) {
    std::vector<std::string> fields;
    if (params.materialProperties.count(l)) fields = {"E", "nu", "density"};
    if (params.preprocess.names.count(l)) fields.push_back("name");
    std::string f;
    for (const auto& x : fields) f += (f.empty() ? "" : "|") + x;
    keys += (keys.empty() ? "" : ", ") + ("material." + std::to_string(l) + "." + f);
  }
  return {ErrorCode::InvalidArgument,
          what + " has no label " + list(unknown) + ", but the parameters set " + keys +
              ". Its materials are labels " + (present.empty() ? std::string("(none)") : list(present)) +
              ". Use one of those labels (see `femesher info`), or remove the setting from --set, "
              "the parameter file or the panel's material table."};
}

Status validate(const MeshingParameters& p) {
  if (p.preprocess.minVoxels < 1) return {ErrorCode::InvalidArgument, "min_voxels must be >= 1"};
  if (p.sizing.hMax > 0 && p.sizing.hMin > p.sizing.hMax)
    return {ErrorCode::InvalidArgument, "h_min must not exceed h_max"};
  if (p.indicators.sigma < 0) return {ErrorCode::InvalidArgument, "smoothing_sigma must be >= 0"};
  if (p.volume.maxRadiusEdgeRatio != 0 && p.volume.maxRadiusEdgeRatio < 1.05)
    return {ErrorCode::InvalidArgument,
            "max_radius_edge_ratio must be 0 (off) or >= 1.05; lower bounds do not terminate"};
  if (p.volume.minDihedralAngle < 0 || p.volume.minDihedralAngle > 18)
    return {ErrorCode::InvalidArgument, "min_dihedral_angle must be in [0, 18] degrees"};
  return Status::ok();
}

}  // namespace femesher
