// SPDX-License-Identifier: GPL-3.0-or-later
// femesher: command-line front end of FEMesherLogic (batch meshing, inspection, Slicer CLI).
#include "Batch.h"
#include "CliCommon.h"
#include "CliProgress.h"
#include "Inspect.h"
#include "SlicerXml.h"

#include <femesher/Parameters.h>
#include <femesher/HipPhantom.h>
#include <femesher/MemoryEstimate.h>
#include <femesher/Parallel.h>
#include <femesher/Phantom.h>
#include <femesher/Pipeline.h>
#include <femesher/RunReport.h>
#include <femesher/Spelling.h>
#include <femesher/Version.h>
#include <femesher/io/AtomicFile.h>
#include <femesher/io/LabelMapIO.h>
#include <femesher/io/LabelTable.h>
#include <femesher/io/MeshIO.h>
#include <femesher/stages/Fidelity.h>
#include <femesher/stages/MedialAxis.h>
#include <femesher/stages/Quality.h>
#include <femesher/stages/SizingField.h>

#include <CLI/CLI.hpp>

#include <algorithm>
#include <optional>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>

using namespace femesher;
namespace fs = std::filesystem;

using cli::fail;
using cli::readNamedLabelMap;

namespace {

using cli::CancellableCommand;
using cli::ReadingScope;

/// A FileWriter writing `text` and a newline.
FileWriter textWriter(const std::string& path, const std::string& text) {
  return [path, text](const std::string& tmp) {
    std::ofstream out(tmp);
    out << text << "\n";
    out.close();
    if (!out)
      return Status(ErrorCode::WriteFailed,
                    "Cannot write '" + path + "': the disk may be full or the folder not writable.");
    return Status::ok();
  };
}

Status writeText(const std::string& path, const std::string& text) {
  return writeAtomically(path, textWriter(path, text));
}

/// Checks outputs before a long run: supported extension, a format that can hold the
/// element order asked for (element_order 2: not .mesh or .stl), an existing folder, not a
/// folder itself, and no two outputs (meshes and `others`: report, saved parameters) the same file.
Status checkOutputs(const std::vector<std::string>& outputs, const MeshingParameters& params,
                    const std::vector<std::string>& others = {}) {
  const ExportOptions eo = exportOptionsFrom(params);
  std::vector<std::string> all = outputs;
  all.insert(all.end(), others.begin(), others.end());
  if (Status s = checkDistinctOutputs(all); !s) return s;
  for (const auto& o : all) {
    if (o.empty()) continue;
    if (std::find(outputs.begin(), outputs.end(), o) != outputs.end())
      if (Status s = checkExportable(o, eo); !s) return s;
    const fs::path dir = fs::path(o).has_parent_path() ? fs::path(o).parent_path() : fs::path(".");
    if (!fs::is_directory(dir))
      return {ErrorCode::WriteFailed, "Output '" + o + "': folder '" + dir.string() +
                                          "' does not exist. Create it or choose another path."};
    if (fs::is_directory(o))
      return {ErrorCode::WriteFailed, "Output '" + o + "' is a folder. Give a file name in it."};
  }
  return Status::ok();
}

struct MeshOptions {
  std::string input;
  std::vector<std::string> outputs;
  std::string preset = "default";
  std::string parameterFile;
  std::vector<std::string> sets;
  int threads = -1;
  long long seed = -1;
  std::string report;
  std::string saveParameters;
  std::string labelNames;  ///< colour table naming the labels (--label-names)
  bool quiet = false;
  bool memoryEstimate = false;  ///< --memory-estimate: print the estimate (JSON), mesh nothing
  bool slicerInvocation = false;  ///< run as Slicer runs CLI modules (no subcommand)
  std::map<std::string, std::string> direct;   ///< --<parameter-key> value (one flag per parameter)
  std::map<std::string, std::string> negated;  ///< --no-<boolean-key> [value]: key = !value
};

std::string flagName(const std::string& key) {
  std::string f = key;
  for (auto& c : f)
    if (c == '_' || c == '.') c = '-';
  return f;
}

/// Every spelling of a boolean parameter's flags: --k-e-y, --k_e_y, --no-k-e-y, --no_k_e_y.
std::vector<std::string> booleanFlagSpellings() {
  std::vector<std::string> flags;
  for (const auto& d : parameterDescriptors()) {
    if (d.type != "bool") continue;
    flags.push_back("--" + flagName(d.key));
    flags.push_back("--" + cli::semName(d.key));
    flags.push_back("--no-" + flagName(d.key));
    flags.push_back("--no_" + cli::semName(d.key));
  }
  return flags;
}

/// Slicer (and common usage) gives a true boolean as a bare flag. A boolean flag followed by a
/// boolean word (true/false/on/off/yes/no/1/0) takes it as its value, as before; a bare one
/// becomes `--flag=true`. Everything else is passed through unchanged.
std::vector<std::string> expandBareBooleanFlags(const std::vector<std::string>& args) {
  static const std::vector<std::string> flags = booleanFlagSpellings();
  std::vector<std::string> out;
  for (size_t i = 0; i < args.size(); ++i) {
    if (std::find(flags.begin(), flags.end(), args[i]) == flags.end()) {
      out.push_back(args[i]);
      continue;
    }
    bool ignored = false;
    if (i + 1 < args.size() && parseBoolean(args[i + 1], ignored)) {
      out.push_back(args[i] + "=" + args[i + 1]);
      ++i;
    } else {
      out.push_back(args[i] + "=true");
    }
  }
  return out;
}

Result<MeshingParameters> buildParameters(const MeshOptions& o) {
  auto p = presetParameters(o.preset);
  if (!p) return p;
  MeshingParameters params = p.value();
  if (!o.parameterFile.empty()) {
    auto f = loadParametersFile(o.parameterFile, params);
    if (!f) return f;
    params = f.value();
  }
  for (const auto& kv : o.sets) {
    const auto eq = kv.find('=');
    if (eq == std::string::npos)
      return Result<MeshingParameters>(ErrorCode::InvalidArgument,
                                       "--set expects key=value, got '" + kv + "'");
    Status s = setParameter(params, kv.substr(0, eq), kv.substr(eq + 1));
    if (!s) return s;
  }
  for (const auto& [key, value] : o.direct) {
    Status s = setParameter(params, key, value);
    if (!s) return s;
  }
  for (const auto& [key, value] : o.negated) {
    bool off = false;
    if (!parseBoolean(value, off))
      return Result<MeshingParameters>(ErrorCode::InvalidArgument,
                                       "--no-" + flagName(key) + " '" + value +
                                           "': use no value, or true/false (on/off, yes/no, 1/0)");
    bool on = false;
    const auto d = o.direct.find(key);
    if (d != o.direct.end() && parseBoolean(d->second, on) && on == off)
      return Result<MeshingParameters>(ErrorCode::InvalidArgument,
                                       "--" + flagName(key) + " " + d->second + " and --no-" +
                                           flagName(key) + " " + value + " contradict each other");
    Status s = setParameter(params, key, off ? "false" : "true");
    if (!s) return s;
  }
  if (o.threads >= 0) params.run.threads = o.threads;
  if (o.seed >= 0) params.run.seed = uint64_t(o.seed);
  if (Status s = validate(params); !s) return s;
  return params;
}

struct CancellableRun;
int writeRunOutputs(const PipelineResult& result, const MeshingParameters& params,
                    const MeshOptions& o, const std::string& source, cli::CliProgress& progress,
                    CancellableRun& run);

/// A run context showing its progress on `progress` and cancelled by Ctrl-C / SIGTERM while it
/// lives: a run makes it before reading its input and keeps it until its last output is renamed.
struct CancellableRun {
  explicit CancellableRun(cli::CliProgress& progress) {
    ctx.setProgressCallback(
        [&progress](const std::string& st, double f, double t) { progress.update(st, f, t); });
    ctx.setLogCallback([&progress](LogLevel l, const std::string& m) { progress.log(l, m); });
    cli::cancelOnSignal(&ctx);
  }
  ~CancellableRun() { cli::cancelOnSignal(nullptr); }
  CancellableRun(const CancellableRun&) = delete;
  CancellableRun& operator=(const CancellableRun&) = delete;
  RunContext ctx;
};

/// Removes what runs killed by SIGKILL left in the output folders (AtomicFile.h) and says so.
void removeStaleFiles(const std::vector<std::string>& outputs, bool quiet) {
  for (const auto& f : removeStaleTemporaries(outputs))
    if (!quiet) std::fprintf(stderr, "note: removed %s, a temporary file of a run that ended "
                                     "without finishing\n", f.c_str());
}

int runMesh(const MeshOptions& o) {
  auto params = buildParameters(o);
  if (!params) return fail(params.status());
  if (o.memoryEstimate) {  // for `batch` and the Snakemake workflow: the memory to plan for
    auto volume = readNamedLabelMap(o.input, o.labelNames);
    if (!volume) return fail(volume.status());
    const int threads = resolveThreads(params->run.threads);
    std::fputs(cli::memoryEstimateJson(o.input, estimateRunMemory(volume.value(), params.value()),
                                       threads).c_str(), stdout);
    return 0;
  }
  if (o.outputs.empty() && o.report.empty() && o.saveParameters.empty())
    return fail({ErrorCode::InvalidArgument, "Nothing to write: give at least one -o OUTPUT."});
  if (Status s = checkOutputs(o.outputs, params.value(), {o.report, o.saveParameters}); !s)
    return fail(s);
  std::vector<std::string> all = o.outputs;
  all.insert(all.end(), {o.report, o.saveParameters});
  removeStaleFiles(all, o.quiet);
  // Only the parameters: nothing to read or mesh. Otherwise they are written with the outputs.
  if (o.outputs.empty() && o.report.empty()) {
    const Status s = writeText(o.saveParameters, parametersToJson(params.value()));
    return s ? 0 : fail(s);
  }

  cli::CliProgress progress(cli::CliProgress::detect(o.quiet, o.slicerInvocation));
  CancellableRun run(progress);  // Ctrl-C / SIGTERM from here to the last rename: exit 12
  progress.start("Meshing " + o.input);
  auto volume = [&] {
    ReadingScope reading;
    return readNamedLabelMap(o.input, o.labelNames);
  }();
  if (!volume) {
    progress.finish(false);
    return fail(volume.status());
  }
  auto result = run.ctx.isCanceled()
                    ? Result<PipelineResult>(ErrorCode::Canceled, "The run was canceled.")
                    : runPipeline(volume.value(), params.value(), run.ctx);
  if (!result) {
    progress.finish(false);
    const Status& s = result.status();
    const bool meshing = s.code() == ErrorCode::MeshingFailed || s.code() == ErrorCode::Internal;
    if (!meshing || s.message().find(o.input) != std::string::npos) return fail(s);
    return fail(Status(s.code(), o.input + ": " + s.message()));  // name the file
  }
  return writeRunOutputs(result.value(), params.value(), o, o.input, progress, run);
}

/// The run's summary for people: counts, low-angle tets, Dice range and boundary distances (when
/// fidelity was computed) and the files written; the "Elements:" line (worst angle and status)
/// follows it.
std::string runSummary(const PipelineResult& r, const std::vector<std::string>& written) {
  std::string text;
  char line[512];
  auto add = [&](const char* label, const std::string& value) {
    std::snprintf(line, sizeof line, "  %-14s %s\n", label, value.c_str());
    text += line;
  };
  const size_t tets = r.mesh.tets.size();
  std::snprintf(line, sizeof line, "%zu tets, %zu vertices, %zu materials, %.1f s", tets,
                r.mesh.points.size(), r.mesh.materials.size(), r.totalSeconds);
  text += "Summary\n";
  add("Mesh", line);
  const std::pair<int, size_t> below[] = {{5, r.quality.minDihedralBelow5},
                                          {10, r.quality.minDihedralBelow10},
                                          {15, r.quality.minDihedralBelow15}};
  for (const auto& [deg, count] : below) {
    char label[32];
    std::snprintf(label, sizeof label, "Below %d deg", deg);
    std::snprintf(line, sizeof line, "%zu tets (%.3f %%)", count,
                  tets ? 100.0 * double(count) / double(tets) : 0.0);
    add(label, line);
  }
  if (r.hasFidelity && !r.fidelity.materials.empty()) {
    const auto& m = r.fidelity.materials;
    const auto [lo, hi] = std::minmax_element(
        m.begin(), m.end(), [](const auto& a, const auto& b) { return a.dice < b.dice; });
    // The default name is "label N" already: say it once.
    const std::string plain = "label " + std::to_string(lo->label);
    const std::string who =
        lo->name.empty() || lo->name == plain ? plain : lo->name + ", " + plain;
    std::snprintf(line, sizeof line, "%.4f lowest (%s) .. %.4f highest", lo->dice, who.c_str(),
                  hi->dice);
    add("Volume Dice", line);
    std::snprintf(line, sizeof line,
                  "%.3f voxels mesh to labels, %.3f voxels labels to mesh (voxel %.3g mm)",
                  r.fidelity.meshToLabels.p99, r.fidelity.labelsToMesh.p99, r.fidelity.voxelSize);
    add("Boundary p99", line);
  }
  std::map<std::string, double> counts(r.counts.begin(), r.counts.end());
  if (counts.count("quadratic_curved_nodes")) {
    std::snprintf(line, sizeof line,
                  "%.0f mid-edge nodes on interfaces curved (%.0f part of the way), %.0f kept "
                  "straight; worst scaled Jacobian %.3f",
                  counts["quadratic_curved_nodes"], counts["quadratic_partly_curved_nodes"],
                  counts["quadratic_straight_kept"], counts["quadratic_worst_scaled_jacobian"]);
    add("10-node tets", line);
  }
  for (const auto& c : r.contacts) {
    std::snprintf(line, sizeof line, "%d:%d split, %zu interface triangles, %zu nodes duplicated",
                  c.labelA, c.labelB, c.facesA.size(), c.duplicatedNodes);
    add("Contact pair", line);
  }
  std::string files;
  for (const auto& f : written) files += (files.empty() ? "" : ", ") + f;
  if (!files.empty()) add("Wrote", files);
  return text;
}

/// Writes a finished run's meshes, report and parameters (--save-parameters) as one transaction
/// that a signal cancels up to its last rename, then its summary on stderr.
int writeRunOutputs(const PipelineResult& result, const MeshingParameters& params,
                    const MeshOptions& o, const std::string& source, cli::CliProgress& progress,
                    CancellableRun& run) {
  ExportOptions eo = exportOptionsFrom(params);
  eo.provenance = "femesher " FEMESHER_VERSION " from " + source;
  eo.contacts = result.contacts;
  eo.nodeSets = result.boxNodeSets;
  eo.midEdgeNodes = result.midEdgeNodes;
  std::vector<std::string> exportWarnings;
  // Every output to a temporary file first; renamed into place only when all were written.
  OutputTransaction outputs;
  outputs.setCancelFlag(run.ctx.cancelToken().flag());
  Status status;
  for (const auto& out : o.outputs) {
    status = outputs.stage(out, [&](const std::string& tmp) { return writeMesh(result.mesh, tmp, eo); });
    if (!status) break;
    if (std::string w = defaultPropertiesWarning(result.mesh, out, eo); !w.empty())
      exportWarnings.push_back(w);
  }
  if (status && !o.report.empty())
    status = outputs.stage(o.report, textWriter(o.report, addReportWarnings(result.reportJson,
                                                                            exportWarnings)));
  if (status && !o.saveParameters.empty())
    status = outputs.stage(o.saveParameters,
                           textWriter(o.saveParameters, parametersToJson(params)));
  if (status) status = outputs.commit();
  if (!status) {
    progress.finish(false);
    return fail(status);
  }
  progress.finish(true);
  for (const auto& w : exportWarnings) std::fprintf(stderr, "warning: %s\n", w.c_str());
  std::vector<std::string> written = o.outputs;
  if (!o.report.empty()) written.push_back(o.report);
  if (!o.saveParameters.empty()) written.push_back(o.saveParameters);
  if (!o.quiet && progress.mode() != cli::CliProgress::Mode::Slicer)
    std::fputs(runSummary(result, written).c_str(), stderr);
  // The element check's one line, even with --quiet when the status is poor_elements.
  const MeshCheckResult& check = result.meshCheck;
  if (!o.quiet || check.poor())
    std::fprintf(stderr, "Elements: %s\n", meshCheckSummary(check).c_str());
  return 0;
}

/// What `optimize` does with a mesh of 10-node tets: it improves their corner tets; the outputs
/// are 4-node tets unless element_order=2 asks for 10-node ones, made anew from the improved mesh.
std::string quadraticInputNote(const std::string& meshPath, int elementOrder) {
  return "note: " + meshPath +
         " holds 10-node tetrahedra; Optimize works on their corner (4-node) " +
         "tets and the file's mid-edge nodes are dropped. " +
         (elementOrder == 2
              ? "element_order=2: the outputs get new mid-edge nodes, curved onto the label map's "
                "interfaces."
              : "The outputs are linear (4-node) tets; add --set element_order=2 for 10-node tets "
                "(new mid-edge nodes, curved onto the label map's interfaces).");
}

/// `femesher optimize`: the Optimize stage on an existing labelled tet mesh, against the smooth
/// interfaces of the label map it was made from; writes the improved mesh and its report.
int runOptimize(const std::string& meshPath, const std::string& labelsPath, const MeshOptions& o) {
  auto params = buildParameters(o);
  if (!params) return fail(params.status());
  if (o.outputs.empty()) return fail({ErrorCode::InvalidArgument, "Nothing to write: give -o OUTPUT."});
  if (Status s = checkOutputs(o.outputs, params.value(), {o.report}); !s) return fail(s);
  std::vector<std::string> all = o.outputs;
  all.push_back(o.report);
  removeStaleFiles(all, o.quiet);
  cli::CliProgress progress(cli::CliProgress::detect(o.quiet, false));
  CancellableRun run(progress);  // Ctrl-C / SIGTERM from here to the last rename: exit 12
  progress.start("Optimizing " + meshPath);
  Result<MeshFile> mesh(ErrorCode::Internal, "");
  Result<LabelVolume> labels(ErrorCode::Internal, "");
  {
    ReadingScope reading;
    mesh = readMeshFile(meshPath);
    labels = mesh ? readLabelMap(labelsPath) : Result<LabelVolume>(mesh.status());
  }
  if (!mesh || !labels) {
    progress.finish(false);
    return fail(!mesh ? mesh.status() : labels.status());
  }
  if (mesh->elementOrder == 2)
    std::fprintf(stderr, "%s\n", quadraticInputNote(meshPath, params->elementOrder).c_str());
  auto result = run.ctx.isCanceled()
                    ? Result<PipelineResult>(ErrorCode::Canceled, "The run was canceled.")
                    : optimizeMesh(labels.value(), mesh->mesh, params.value(), run.ctx);
  if (!result) {
    progress.finish(false);
    if (result.status().code() == ErrorCode::Canceled) return fail(result.status());
    return fail(Status(result.status().code(), meshPath + ": " + result.status().message()));
  }
  return writeRunOutputs(result.value(), params.value(), o, meshPath, progress, run);
}

/// `femesher sizing`: the adaptive sizing field (target edge length, mm) as a float image: the
/// field a mesh run with the same parameters uses, on its working grid (the labelled box plus a
/// margin), placed in the input's physical space.
int runSizing(const std::string& input, const std::string& output, const MeshOptions& o) {
  auto params = buildParameters(o);
  if (!params) return fail(params.status());
  CancellableCommand command;
  std::optional<ReadingScope> computing(std::in_place);  // nothing written until the field
  auto volume = readLabelMap(input);
  if (!volume) return fail(volume.status());
  MeshingParameters p = params.value();
  p.sizing.mode = SizingMode::Adaptive;
  RunContext& ctx = command.ctx;
  std::shared_ptr<const SizingField> field;
  LabelVolume geometry;
  if (Status s = runGuarded([&] {
        MeshingRun run(volume.value(), p, ctx);
        run.runThrough(StageId::SizingField);
        field = run.state().sizingField;
        geometry = run.workingGridGeometry();
      });
      !s)
    return fail(s);
  computing.reset();  // a signal from here on stops the write before its rename
  if (Status s = writeScalarVolume(geometry, field->values(ctx.threads()), output); !s) return fail(s);
  std::fprintf(stderr, "wrote %s: target edge length %.3g .. %.3g mm (%zu medial voxels)\n",
               output.c_str(), field->lowest, field->highest, field->medialVoxels);
  return 0;
}

void addMeshOptions(CLI::App* cmd, MeshOptions& o, bool positionalOutput) {
  cmd->add_option("input", o.input, "Label map (.nrrd .nhdr .nii .nii.gz .mha .mhd .seg.nrrd)")
      ->required();
  if (positionalOutput) cmd->add_option("output", o.outputs, "Output mesh");
  cmd->add_option("-o,--output", o.outputs,
                  "Output mesh; repeat for several formats (.vtu .inp .msh .mesh .feb .stl)");
  cmd->add_option("--preset", o.preset, "Parameter preset: coarse, default, fine");
  cmd->add_option("--parameters", o.parameterFile, "JSON parameter file (as saved by the app)");
  cmd->add_option("--set", o.sets, "Set a parameter: key=value (repeatable; see `femesher parameters`)");
  cmd->add_option("--threads", o.threads, "Worker threads (0 = all cores)");
  cmd->add_option("--seed", o.seed, "Random seed");
  cmd->add_option("--report", o.report, "Write the run report (JSON)");
  cmd->add_option("--save-parameters", o.saveParameters, "Write the effective parameters (JSON)");
  cmd->add_option("--label-names,--label_names", o.labelNames,
                  "Colour table naming the labels: 3D Slicer .ctbl/.txt or .csv, or an ITK-SNAP "
                  "label description file (material.<label>.name overrides it)");
  cmd->add_flag("-q,--quiet", o.quiet, "Only warnings and errors");
  if (!positionalOutput)
    cmd->add_flag("--memory-estimate", o.memoryEstimate,
                  "Print the run's memory estimate (JSON) and exit without meshing");
  for (const auto& d : parameterDescriptors()) {
    const std::string key = d.key;
    if (key == "threads" || key == "seed") continue;  // dedicated options above
    // --target-edge-length and --target_edge_length (the spelling of `--xml`, which Slicer uses).
    std::string names = "--" + flagName(d.key);
    if (cli::semName(d.key) != flagName(d.key)) names += ",--" + cli::semName(d.key);
    cmd->add_option_function<std::string>(
           names, [&o, key](const std::string& v) { o.direct[key] = v; },
           d.help + (d.unit.empty() ? "" : " [" + d.unit + "]") +
               (d.type == "bool" ? " A bare flag means true." : ""))
        ->group("Parameters");
    if (d.type != "bool") continue;
    cmd->add_option_function<std::string>(
           "--no-" + flagName(d.key) + ",--no_" + cli::semName(d.key),
           [&o, key](const std::string& v) { o.negated[key] = v; },
           "Turn " + d.key + " off (a bare flag; --no-" + flagName(d.key) + " false turns it on).")
        ->group("Parameters");
  }
}

/// Every long and short flag of `cmd` ("--voxel-refinement", "-o", ...).
std::vector<std::string> flagNames(const CLI::App* cmd) {
  std::vector<std::string> names;
  for (const CLI::Option* opt : cmd->get_options()) {
    for (const auto& l : opt->get_lnames()) names.push_back("--" + l);
    for (const auto& s : opt->get_snames()) names.push_back("-" + s);
  }
  return names;
}

/// A failed parse. CLI11's own message, except for unknown flags that are close to a known one
/// of the command being parsed: those get an error naming the flag and the likely one.
int parseFailure(CLI::App& app, const CLI::ParseError& e) {
  if (dynamic_cast<const CLI::ExtrasError*>(&e)) {
    const CLI::App* cmd = &app;
    if (!app.get_subcommands().empty()) cmd = app.get_subcommands().front();
    std::vector<std::string> known = flagNames(cmd);
    if (cmd != &app)
      for (const auto& f : flagNames(&app)) known.push_back(f);
    std::string message;
    for (const auto& arg : app.remaining(true)) {
      if (arg.size() < 2 || arg[0] != '-') continue;
      const std::string flag = arg.substr(0, arg.find('='));
      const std::string hint = didYouMean(flag, known);
      if (!hint.empty())
        message += (message.empty() ? "" : "\n") + std::string("error [") +
                   errorCodeName(ErrorCode::InvalidArgument) + "]: unknown option '" + flag +
                   "'." + hint;
    }
    if (!message.empty()) {
      std::fprintf(stderr, "%s\nRun with --help for more information.\n", message.c_str());
      return exitCodeFor(ErrorCode::InvalidArgument);
    }
  }
  const int rc = app.exit(e);
  return rc == 0 ? 0 : exitCodeFor(ErrorCode::InvalidArgument);
}

}  // namespace

int main(int argc, char** argv) {
  // Slicer runs CLI modules as `femesher [--flags] input output` (no sub-command).
  static const std::vector<std::string> commands = {"mesh", "batch", "quality", "info", "phantom",
                                                    "medial-axis", "sizing", "optimize",
                                                    "parameters", "--xml", "--version", "-h",
                                                    "--help"};
  bool slicerStyle = argc > 1;
  for (int i = 1; i < argc; ++i)
    if (std::find(commands.begin(), commands.end(), argv[i]) != commands.end()) slicerStyle = false;
  // A misspelt command ("mseh") would otherwise be taken for Slicer's input file.
  if (slicerStyle && argv[1][0] != '-' && !fs::exists(argv[1])) {
    const std::vector<std::string> names(commands.begin(), commands.begin() + 9);
    if (std::string hint = didYouMean(argv[1], names); !hint.empty())
      return fail({ErrorCode::InvalidArgument,
                   std::string("Unknown command '") + argv[1] + "'." + hint +
                       " Commands: mesh, batch, quality, info, phantom, medial-axis, sizing, optimize, "
                       "parameters (see femesher --help)."});
  }
  // Bare boolean flags (`--voxel_refinement`, `--no_voxel_refinement`) become `--flag=true`.
  std::vector<std::string> args =
      expandBareBooleanFlags(std::vector<std::string>(argv + 1, argv + argc));
  std::reverse(args.begin(), args.end());  // CLI11 parses a reversed vector of the arguments

  CLI::App app{"FEMesher " FEMESHER_VERSION
               ": conformal multi-material tetrahedral meshes from label maps"};
  app.name(argv[0]);
  app.set_version_flag("--version", std::string("femesher ") + FEMESHER_VERSION + " (ITK " +
                                        FEMESHER_ITK_VERSION + ", VTK " + FEMESHER_VTK_VERSION +
                                        ", CGAL " + FEMESHER_CGAL_VERSION + ", TetGen " +
                                        FEMESHER_TETGEN_VERSION + ")");
  bool xml = false;
  app.add_flag("--xml", xml, "Print the Slicer CLI module description and exit");

  MeshOptions meshOpts;
  meshOpts.slicerInvocation = slicerStyle;
  if (slicerStyle) {
    addMeshOptions(&app, meshOpts, true);
    try {
      app.parse(args);
    } catch (const CLI::ParseError& e) {
      return parseFailure(app, e);
    }
    return runMesh(meshOpts);
  }

  auto* mesh = app.add_subcommand("mesh", "Mesh a label map");
  addMeshOptions(mesh, meshOpts, false);

  cli::BatchOptions batchOpts;
  auto* batch = cli::addBatchCommand(app, batchOpts);

  std::string qualityMesh, qualityLabels, qualityRaster;
  bool qualityJson = false;
  auto* quality = app.add_subcommand("quality", "Element quality (and fidelity) of a mesh");
  quality->add_option("mesh", qualityMesh, "Mesh (.vtu .vtk .msh .inp .mesh; 4- or 10-node tets)")
      ->required();
  quality->add_option("--labels", qualityLabels, "Label map to compare with (fidelity)");
  quality->add_option("--raster", qualityRaster,
                      "Write the mesh sampled on the label map's voxel centres (label of the tet "
                      "containing each centre, 0 outside) to this label map file: compare it with "
                      "--labels to see where they disagree");
  quality->add_flag("--json", qualityJson, "JSON output");

  std::string infoInput, infoNames;
  bool infoJson = false;
  auto* info = app.add_subcommand("info", "Describe a label map");
  info->add_option("input", infoInput, "Label map")->required();
  info->add_option("--label-names,--label_names", infoNames, "Colour table naming the labels (as for mesh)");
  info->add_flag("--json", infoJson, "JSON output");

  std::string phantomOut;
  double phantomVoxel = 0, phantomScale = 0;
  bool phantomHip = false;
  auto* phantom = app.add_subcommand(
      "phantom", "Write a built-in label map: the 5-material proximal femur (64 x 64 x 96 voxels), "
                 "or with --hip a clinical-size CT of both hips (512 x 512 x 400, 10 materials)");
  phantom->add_option("output", phantomOut, "Output label map (.nrrd .nii.gz .mha)")->required();
  phantom->add_option("--voxel-size", phantomVoxel, "Femur phantom: voxel size in mm (default 1)");
  phantom->add_flag("--hip", phantomHip,
                    "The hip phantom: 512 x 512 x 400 voxels of 0.7 x 0.7 x 1 mm, 10 materials "
                    "(pelvis and femur cortical and trabecular bone, marrow, cartilage, an implant "
                    "with stem and cup, muscle, fat, a 1-2 voxel subchondral plate)");
  auto* phantomScaleOpt = phantom->add_option("--scale", phantomScale,
                      "Hip phantom: the same anatomy on round(512 s) x round(512 s) x round(400 s) "
                      "voxels, s in (0.05, 2] (default 1)");

  std::string maInput, maOutput, maLabel, maPrune;
  double maGamma = -1, maGammaConstant = -1;
  auto* medial = app.add_subcommand("medial-axis", "Write the Integer Medial Axis a mesh run computes (on its working grid) as a label image");
  medial->add_option("input", maInput, "Label map")->required();
  medial->add_option("-o,--output", maOutput, "Output label image (.nrrd .nii.gz .mha)")->required();
  medial->add_option("--label", maLabel, "Only this label (default: every label, background too)");
  medial->add_option("--prune", maPrune, "none, constant, linear, sqrt, constant-linear (default)");
  medial->add_option("--gamma", maGamma, "Pruning parameter (see MedialAxis.h for its scaling)");
  medial->add_option("--gamma-constant", maGammaConstant, "Constant floor of constant-linear (voxels)");

  std::string szInput, szOutput;
  MeshOptions szOpts;
  auto* sizingCmd = app.add_subcommand("sizing", "Write the adaptive sizing field a mesh run uses (mm, on its working grid) as a float image");
  sizingCmd->add_option("input", szInput, "Label map")->required();
  sizingCmd->add_option("-o,--output", szOutput, "Output image (.nrrd .nii.gz .mha)")->required();
  sizingCmd->add_option("--preset", szOpts.preset, "Parameter preset: coarse, default, fine");
  sizingCmd->add_option("--set", szOpts.sets, "Set a parameter: key=value (sizing_scale, h_min, h_max, gradation)");

  std::string optMesh, optLabels;
  MeshOptions optOpts;
  auto* optimizeCmd = app.add_subcommand(
      "optimize", "Improve an existing labelled tet mesh against the label map it was made from");
  optimizeCmd->add_option("mesh", optMesh, "Mesh (.vtu .vtk .msh .inp .mesh; 4- or 10-node tets)")
      ->required();
  optimizeCmd->add_option("--labels", optLabels, "The label map the mesh was made from")->required();
  optimizeCmd->add_option("-o,--output", optOpts.outputs, "Improved mesh; repeat for several formats")
      ->required();
  optimizeCmd->add_option("--parameters", optOpts.parameterFile, "JSON parameter file");
  optimizeCmd->add_option("--set", optOpts.sets, "Set a parameter: key=value (optimize_min_dihedral, ...)");
  optimizeCmd->add_option("--threads", optOpts.threads, "Worker threads (0 = all cores)");
  optimizeCmd->add_option("--report", optOpts.report, "Write the run report (JSON)");
  optimizeCmd->add_flag("-q,--quiet", optOpts.quiet, "Only warnings and errors");

  bool paramsJson = false;
  auto* params = app.add_subcommand("parameters", "List the parameters accepted by --set");
  params->add_flag("--json", paramsJson, "JSON output: key, type, unit, default, minimum, maximum");

  try {
    app.parse(args);
  } catch (const CLI::ParseError& e) {
    return parseFailure(app, e);
  }
  if (xml) {
    std::fputs(cli::slicerXml().c_str(), stdout);
    return 0;
  }
  try {
    if (*mesh) return runMesh(meshOpts);
    if (*batch) return cli::runBatch(batchOpts);
    if (*optimizeCmd) return runOptimize(optMesh, optLabels, optOpts);
    if (*quality) return cli::runQuality(qualityMesh, qualityLabels, qualityRaster, qualityJson);
    if (*info) return cli::runInfo(infoInput, infoNames, infoJson);
    if (*phantom) return cli::runPhantom(phantomOut, phantomVoxel, phantomHip, phantomScaleOpt, phantomScale);
    if (*medial) return cli::runMedialAxis(maInput, maOutput, maLabel, maPrune, maGamma, maGammaConstant);
    if (*sizingCmd) return runSizing(szInput, szOutput, szOpts);
    if (*params && paramsJson) {
      std::printf("%s\n", parameterDescriptorsToJson().c_str());
      return 0;
    }
    if (*params) {
      for (const auto& d : parameterDescriptors())
        std::printf("%-24s %-7s default %-10s %-8s %s\n", d.key.c_str(), d.type.c_str(),
                    d.defaultValue.c_str(), d.unit.c_str(), d.help.c_str());
      std::printf("%-24s %-7s %-18s %-8s %s\n", "material.<label>.E", "double", "", "MPa",
                  "Young's modulus of one material in solver exports (also .nu, .density).");
      std::printf("%-24s %-7s %-18s %-8s %s\n", "material.<label>.name", "string", "", "",
                  "Name of one material in the mesh, every export and the report (overrides the "
                  "label map's and --label-names').");
      std::printf("%-24s %-7s %-18s %-8s %s\n", "material.<label>.exclude", "choice", "default no",
                  "", "Leave the material out: 'background' (a cavity or a cut) or 'merge' (its "
                  "voxels join the neighbouring material); 'no' meshes it.");
      return 0;
    }
  } catch (const Error& e) {
    return fail(e.status());
  } catch (const std::exception& e) {
    return fail({ErrorCode::Internal, e.what()});
  }
  std::fputs(app.help().c_str(), stdout);
  return exitCodeFor(ErrorCode::InvalidArgument);
}
