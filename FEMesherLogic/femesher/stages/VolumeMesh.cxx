// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/RunContext.h>
#include <femesher/Status.h>
#include <femesher/stages/VolumeMesh.h>

#include <tetgen.h>

#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cerrno>
#include <cstring>
#include <map>
#include <sstream>

namespace femesher {

namespace {

const char* tetgenErrorText(int code) {
  switch (code) {
    case 1: return "out of memory";
    case 2: return "internal error";
    case 3: return "the interface surface self-intersects";
    case 4: return "a very small input feature size";
    case 5: return "two very close input facets";
    case 10: return "an input error";
    default: return "an unknown error";
  }
}

double signedVolume(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  const double v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  const double w[3] = {d[0] - a[0], d[1] - a[1], d[2] - a[2]};
  return (u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0]) +
          u[2] * (v[0] * w[1] - v[1] * w[0])) / 6.0;
}

/// TetGen's output as plain arrays.
struct TetgenOutput {
  std::vector<double> points;  // 3 per point
  std::vector<int32_t> tets;   // 4 per tet
  std::vector<double> regions; // 1 per tet (region attribute) or empty
};

/// Runs TetGen in this process; returns false (and the error text) when it throws.
bool runTetgen(const BoundarySurface& s, const std::vector<double>& sizes,
               const std::string& switches, TetgenOutput& result, std::string& error) {
  tetgenio out;
  tetgenio in;
  in.firstnumber = 0;
  in.numberofpoints = int(s.points.size());
  in.pointlist = new REAL[3 * s.points.size()];
  for (size_t i = 0; i < s.points.size(); ++i)
    for (int a = 0; a < 3; ++a) in.pointlist[3 * i + a] = s.points[i][a];
  if (sizes.size() == s.points.size()) {
    in.numberofpointmtrs = 1;
    in.pointmtrlist = new REAL[sizes.size()];
    for (size_t i = 0; i < sizes.size(); ++i) in.pointmtrlist[i] = sizes[i];
  }
  // Interface ids for facet markers.
  std::map<std::pair<uint16_t, uint16_t>, int> ids;
  for (const auto& p : s.trianglePairs) ids.emplace(p, int(ids.size()) + 1);
  in.numberoffacets = int(s.triangles.size());
  in.facetlist = new tetgenio::facet[s.triangles.size()];
  in.facetmarkerlist = new int[s.triangles.size()];
  for (size_t f = 0; f < s.triangles.size(); ++f) {
    tetgenio::facet& fc = in.facetlist[f];
    tetgenio::init(&fc);
    fc.numberofpolygons = 1;
    fc.polygonlist = new tetgenio::polygon[1];
    tetgenio::init(&fc.polygonlist[0]);
    fc.polygonlist[0].numberofvertices = 3;
    fc.polygonlist[0].vertexlist = new int[3];
    for (int k = 0; k < 3; ++k) fc.polygonlist[0].vertexlist[k] = s.triangles[f][k];
    in.facetmarkerlist[f] = ids[s.trianglePairs[f]];
  }
  std::vector<char> sw(switches.begin(), switches.end());
  sw.push_back('\0');
  try {
    tetrahedralize(sw.data(), &in, &out);
  } catch (int code) {
    error = "TetGen stopped with error " + std::to_string(code) + " (" + tetgenErrorText(code) + ")";
    return false;
  } catch (const std::exception& e) {
    error = std::string("TetGen failed: ") + e.what();
    return false;
  }
  if (out.numberoftetrahedra <= 0) {
    error = "TetGen produced no tetrahedra";
    return false;
  }
  result.points.assign(out.pointlist, out.pointlist + 3 * size_t(out.numberofpoints));
  result.tets.assign(out.tetrahedronlist, out.tetrahedronlist + 4 * size_t(out.numberoftetrahedra));
  result.regions.clear();
  if (out.numberoftetrahedronattributes > 0) {
    result.regions.resize(size_t(out.numberoftetrahedra));
    for (int t = 0; t < out.numberoftetrahedra; ++t)
      result.regions[t] = out.tetrahedronattributelist[size_t(t) * out.numberoftetrahedronattributes];
  }
  return true;
}

bool writeAll(int fd, const void* data, size_t n) {
  const char* p = static_cast<const char*>(data);
  while (n > 0) {
    const ssize_t w = ::write(fd, p, n);
    if (w <= 0) return false;
    p += w;
    n -= size_t(w);
  }
  return true;
}

/// Runs TetGen in a child process so that a cancel request can stop it at once (TetGen itself
/// has no cancel hook): the parent polls the cancel token while it reads the result from a pipe,
/// and kills the child when asked to stop. Falls back to in-process when fork() fails.
bool runTetgenCancelable(const BoundarySurface& s, const std::vector<double>& sizes,
                         const std::string& switches, TetgenOutput& result, std::string& error,
                         RunContext& ctx) {
  int fds[2];
  if (::pipe(fds) != 0) return runTetgen(s, sizes, switches, result, error);
  const pid_t pid = ::fork();
  if (pid < 0) {
    ::close(fds[0]);
    ::close(fds[1]);
    return runTetgen(s, sizes, switches, result, error);
  }
  if (pid == 0) {  // child: mesh, stream the result, leave without running any exit handler
    ::close(fds[0]);
    TetgenOutput r;
    std::string err;
    const bool ok = runTetgen(s, sizes, switches, r, err);
    const int32_t status = ok ? 0 : 1;
    bool w = writeAll(fds[1], &status, sizeof status);
    if (ok) {
      const uint64_t n[3] = {r.points.size(), r.tets.size(), r.regions.size()};
      w = w && writeAll(fds[1], n, sizeof n) &&
          writeAll(fds[1], r.points.data(), r.points.size() * sizeof(double)) &&
          writeAll(fds[1], r.tets.data(), r.tets.size() * sizeof(int32_t)) &&
          writeAll(fds[1], r.regions.data(), r.regions.size() * sizeof(double));
    } else {
      const uint64_t len = err.size();
      w = w && writeAll(fds[1], &len, sizeof len) && writeAll(fds[1], err.data(), err.size());
    }
    ::close(fds[1]);
    ::_exit(w ? 0 : 3);
  }
  ::close(fds[1]);
  std::vector<char> buffer;
  char chunk[1 << 16];
  bool canceled = false;
  for (;;) {
    if (ctx.isCanceled()) {
      canceled = true;
      break;
    }
    pollfd pfd{fds[0], POLLIN, 0};
    const int pr = ::poll(&pfd, 1, 100);
    if (pr < 0 && errno != EINTR) break;
    if (pr <= 0) continue;
    const ssize_t n = ::read(fds[0], chunk, sizeof chunk);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    buffer.insert(buffer.end(), chunk, chunk + n);
  }
  ::close(fds[0]);
  if (canceled) ::kill(pid, SIGKILL);
  int wstatus = 0;
  while (::waitpid(pid, &wstatus, 0) < 0 && errno == EINTR) {
  }
  if (canceled) ctx.checkCancel();
  size_t pos = 0;
  auto take = [&](void* dst, size_t n) {
    if (pos + n > buffer.size()) return false;
    std::memcpy(dst, buffer.data() + pos, n);
    pos += n;
    return true;
  };
  int32_t status = -1;
  if (!take(&status, sizeof status)) {
    error = WIFSIGNALED(wstatus) ? "TetGen crashed (signal " + std::to_string(WTERMSIG(wstatus)) + ")"
                                 : std::string("TetGen ended without a result");
    return false;
  }
  if (status != 0) {
    uint64_t len = 0;
    if (take(&len, sizeof len) && pos + len <= buffer.size())
      error.assign(buffer.data() + pos, size_t(len));
    else
      error = "TetGen failed";
    return false;
  }
  uint64_t n[3];
  if (!take(n, sizeof n)) {
    error = "TetGen result was cut short";
    return false;
  }
  result.points.resize(n[0]);
  result.tets.resize(n[1]);
  result.regions.resize(n[2]);
  if (!take(result.points.data(), n[0] * sizeof(double)) ||
      !take(result.tets.data(), n[1] * sizeof(int32_t)) ||
      !take(result.regions.data(), n[2] * sizeof(double))) {
    error = "TetGen result was cut short";
    return false;
  }
  return true;
}

}  // namespace

VolumeMeshResult buildVolumeMesh(const BoundarySurface& s, const VolumeMeshParameters& params,
                                 RunContext& ctx) {
  VolumeMeshResult result;
  std::ostringstream base;
  base << "pzQ";
  if (params.maxRadiusEdgeRatio > 0) {
    base << "q" << params.maxRadiusEdgeRatio;
    if (params.minDihedralAngle > 0) base << "/" << params.minDihedralAngle;
  }
  base << "A";
  if (params.pointSizes.size() == s.points.size() && params.usePointSizes) base << "m";
  if (params.maxTetVolume > 0) base << "a" << params.maxTetVolume;
  base << "O" << params.optimizationLevel;
  // Guard against run-away refinement: at most 40 Steiner points per surface vertex + 1M.
  base << "S" << (40 * s.points.size() + 1000000);

  std::vector<std::pair<std::string, std::string>> attempts;
  if (params.preserveInterfaces) attempts.emplace_back(base.str() + "Y", "tetgen");
  attempts.emplace_back(base.str(), params.preserveInterfaces ? "tetgen-without-Y" : "tetgen");

  for (const auto& [switches, method] : attempts) {
    ctx.checkCancel();
    TetgenOutput out;
    std::string error;
    if (!runTetgenCancelable(s, params.pointSizes, switches, out, error, ctx)) {
      ctx.warn("Volume meshing with TetGen switches '" + switches + "' failed: " + error + ".");
      continue;
    }
    ctx.progress(0.7);
    ctx.checkCancel();
    const int nt = int(out.tets.size() / 4);
    const bool hasRegions = !out.regions.empty();
    std::vector<Vec3> pts(out.points.size() / 3);
    for (size_t i = 0; i < pts.size(); ++i)
      pts[i] = {out.points[3 * i], out.points[3 * i + 1], out.points[3 * i + 2]};
    // Label: per region a volume-weighted vote of the Delaunay labels at tet centroids.
    std::vector<int> region(nt, 0);
    if (hasRegions)
      for (int t = 0; t < nt; ++t)
        region[t] = int(std::lround(out.regions[t]));
    std::map<int, std::map<int, double>> votes;
    std::map<int, int> sampled;
    std::vector<int> tetLabel(nt, -1);
    for (int t = 0; t < nt; ++t) {
      const int32_t* T = &out.tets[4 * size_t(t)];
      const int r = hasRegions ? region[t] : -1 - t;
      if (hasRegions && sampled[r] >= 400) continue;
      const Vec3 c{(pts[T[0]][0] + pts[T[1]][0] + pts[T[2]][0] + pts[T[3]][0]) / 4,
                   (pts[T[0]][1] + pts[T[1]][1] + pts[T[2]][1] + pts[T[3]][1]) / 4,
                   (pts[T[0]][2] + pts[T[1]][2] + pts[T[2]][2] + pts[T[3]][2]) / 4};
      const int l = s.delaunay->labelAt(c);
      if (hasRegions) {
        ++sampled[r];
        votes[r][l] += std::fabs(signedVolume(pts[T[0]], pts[T[1]], pts[T[2]], pts[T[3]]));
      } else {
        tetLabel[t] = l;
      }
      if ((t & 0xFFFF) == 0) ctx.checkCancel();
    }
    std::map<int, int> regionLabel;
    for (const auto& [r, v] : votes) {
      int best = 0;
      double bestW = -1;
      for (const auto& [l, w] : v)
        if (w > bestW) {
          bestW = w;
          best = l;
        }
      regionLabel[r] = best;
    }
    result.regions = hasRegions ? votes.size() : 0;
    // Keep material tets, re-index points.
    std::vector<int32_t> newId(pts.size(), -1);
    for (int t = 0; t < nt; ++t) {
      const int l = hasRegions ? regionLabel[region[t]] : tetLabel[t];
      if (l == 0) {
        ++result.droppedCavityTets;
        continue;
      }
      std::array<int32_t, 4> T;
      for (int k = 0; k < 4; ++k) {
        const int v = out.tets[4 * size_t(t) + k];
        if (newId[v] < 0) {
          newId[v] = int32_t(result.points.size());
          result.points.push_back(pts[v]);
        }
        T[k] = newId[v];
      }
      if (signedVolume(result.points[T[0]], result.points[T[1]], result.points[T[2]],
                       result.points[T[3]]) < 0)
        std::swap(T[2], T[3]);
      result.tets.push_back(T);
      result.labels.push_back(l);
    }
    result.switches = switches;
    result.method = method;
    if (method == "tetgen-without-Y")
      ctx.warn("Interface triangles were split by TetGen (switch Y dropped); the mesh is still "
               "conformal but interfaces have extra vertices.");
    ctx.progress(1.0);
    return result;
  }

  ctx.warn("TetGen could not mesh the interface surface; the labelled Delaunay tets of the "
           "surface samples are returned instead (no quality refinement).");
  s.delaunay->exportTets(result.points, result.tets, result.labels);
  for (auto& T : result.tets)
    if (signedVolume(result.points[T[0]], result.points[T[1]], result.points[T[2]],
                     result.points[T[3]]) < 0)
      std::swap(T[2], T[3]);
  result.method = "delaunay-fallback";
  ctx.progress(1.0);
  return result;
}

}  // namespace femesher
