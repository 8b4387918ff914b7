// SPDX-License-Identifier: GPL-3.0-or-later
// One TetGen problem in this process and the helper's wire format (see TetgenProcess.h).
#include <femesher/stages/internal/TetgenProcess.h>

#include <tetgen.h>

#include <signal.h>
#ifdef __linux__
#include <sys/prctl.h>
#endif
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>

namespace femesher {
namespace volume_detail {

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

}  // namespace

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

/// Everything from `fd` until its end; false on a read error.
bool readAll(int fd, std::vector<char>& out) {
  char chunk[1 << 16];
  for (;;) {
    const ssize_t n = ::read(fd, chunk, sizeof chunk);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) return false;
    if (n == 0) return true;
    out.insert(out.end(), chunk, chunk + n);
  }
}

/// The problem as the worker reads it: the five array sizes, then the arrays (points,
/// triangles, markers, holes, sizes; native layout: writer and reader are the same build).
bool writeInput(int fd, const TetgenInput& in) {
  const uint64_t n[5] = {in.points.size(), in.triangles.size(), in.markers.size(),
                         in.holes.size(), in.sizes.size()};
  return writeAll(fd, n, sizeof n) &&
         writeAll(fd, in.points.data(), in.points.size() * sizeof(Vec3)) &&
         writeAll(fd, in.triangles.data(), in.triangles.size() * sizeof(in.triangles[0])) &&
         writeAll(fd, in.markers.data(), in.markers.size() * sizeof(int)) &&
         writeAll(fd, in.holes.data(), in.holes.size() * sizeof(Vec3)) &&
         writeAll(fd, in.sizes.data(), in.sizes.size() * sizeof(double));
}

bool readInput(const std::vector<char>& b, TetgenInput& in) {
  size_t pos = 0;
  auto take = [&](void* dst, size_t n) {
    if (n > b.size() - pos) return false;
    if (n > 0) std::memcpy(dst, b.data() + pos, n);
    pos += n;
    return true;
  };
  uint64_t n[5];
  if (!take(n, sizeof n)) return false;
  const uint64_t limit = b.size();  // no array holds more elements than the input has bytes
  for (uint64_t x : n)
    if (x > limit) return false;
  in.points.resize(n[0]);
  in.triangles.resize(n[1]);
  in.markers.resize(n[2]);
  in.holes.resize(n[3]);
  in.sizes.resize(n[4]);
  const bool ok = take(in.points.data(), n[0] * sizeof(Vec3)) &&
                  take(in.triangles.data(), n[1] * sizeof(in.triangles[0])) &&
                  take(in.markers.data(), n[2] * sizeof(int)) &&
                  take(in.holes.data(), n[3] * sizeof(Vec3)) &&
                  take(in.sizes.data(), n[4] * sizeof(double));
  if (!ok || pos != b.size() || in.markers.size() != in.triangles.size()) return false;
  for (const auto& t : in.triangles)
    for (int32_t v : t)
      if (v < 0 || uint64_t(v) >= n[0]) return false;
  return true;
}

/// The result of one job as a worker streams it: status, then the arrays or the error text.
void dieWithParent(pid_t parent) {
#ifdef __linux__
  ::prctl(PR_SET_PDEATHSIG, SIGKILL);
#endif
  if (::getppid() != parent) ::_exit(4);
}

bool writeResult(int fd, bool ok, const TetgenOutput& r, const std::string& err) {
  const int32_t status = ok ? 0 : 1;
  bool w = writeAll(fd, &status, sizeof status);
  if (ok) {
    const uint64_t n[3] = {r.points.size(), r.tets.size(), r.regions.size()};
    w = w && writeAll(fd, n, sizeof n) &&
        writeAll(fd, r.points.data(), r.points.size() * sizeof(double)) &&
        writeAll(fd, r.tets.data(), r.tets.size() * sizeof(int32_t)) &&
        writeAll(fd, r.regions.data(), r.regions.size() * sizeof(double));
  } else {
    const uint64_t len = err.size();
    w = w && writeAll(fd, &len, sizeof len) && writeAll(fd, err.data(), err.size());
  }
  return w;
}

/// Runs TetGen in this process; returns false (and the error text) when it throws.
bool runTetgen(const TetgenInput& s, const std::string& switches, TetgenOutput& result,
               std::string& error) {
  tetgenio out;
  tetgenio in;
  in.firstnumber = 0;
  in.numberofpoints = int(s.points.size());
  in.pointlist = new REAL[3 * s.points.size()];
  for (size_t i = 0; i < s.points.size(); ++i)
    for (int a = 0; a < 3; ++a) in.pointlist[3 * i + a] = s.points[i][a];
  if (s.sizes.size() == s.points.size()) {
    in.numberofpointmtrs = 1;
    in.pointmtrlist = new REAL[s.sizes.size()];
    for (size_t i = 0; i < s.sizes.size(); ++i) in.pointmtrlist[i] = s.sizes[i];
  }
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
    in.facetmarkerlist[f] = s.markers[f];
  }
  if (!s.holes.empty()) {
    in.numberofholes = int(s.holes.size());
    in.holelist = new REAL[3 * s.holes.size()];
    for (size_t h = 0; h < s.holes.size(); ++h)
      for (int a = 0; a < 3; ++a) in.holelist[3 * h + a] = s.holes[h][a];
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

int tetgenWorkerMain(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr,
                 "femesher-tetgen-worker: FEMesher's volume meshing starts this helper itself "
                 "(SWITCHES PARENT_PID, the problem on standard input); it is not meant to be run "
                 "by hand.\n");
    return 2;
  }
  dieWithParent(pid_t(std::strtol(argv[2], nullptr, 10)));
  TetgenInput in;
  {
    std::vector<char> bytes;
    if (!readAll(0, bytes) || !readInput(bytes, in)) {
      std::fprintf(stderr, "femesher-tetgen-worker: the problem on standard input is cut short or "
                           "malformed.\n");
      return 2;
    }
  }
  ::close(0);
  // TetGen prints to standard output, which carries the result: its messages go to standard
  // error instead.
  const int out = ::dup(1);
  if (out < 0 || ::dup2(2, 1) < 0) return 3;
  TetgenOutput r;
  std::string err;
  const bool ok = runTetgen(in, argv[1], r, err);
  std::fflush(stdout);
  return writeResult(out, ok, r, err) ? 0 : 3;
}

}  // namespace volume_detail
}  // namespace femesher
