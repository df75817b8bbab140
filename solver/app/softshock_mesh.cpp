// softshock-mesh --spec SPEC.json --out FILE [--mesh-cache DIR [--mesh-cache-bytes N]]
//                [--max-elements N] [--max-end-time S] [--mesh-root DIR]
// Meshes one spec's geometry and writes the mesh (before rim roughness) to FILE in the mesh
// cache's entry format (solver/mesh_cache.hpp; temporary file + rename), through the cache
// when one is given, so a second job of the same geometry finds it there and concurrent
// builders of one geometry mesh it once (the cache's lock dies with a killed process).
//
// softshockd runs it as a child process for every Gmsh mesh: Gmsh cannot be interrupted
// inside the daemon, a child can be killed (server/jobs/mesh_process.hpp). It dies with the
// thread that started it (PR_SET_PDEATHSIG), so a daemon killed meanwhile leaves no orphan
// meshing on.
//
// stdout: {"meshing_time_s": S, "mesh_cache": "miss", "warning": "..."}. Exit codes: 0 done,
// 2 invalid spec or usage, 1 failure; the reason is the last line on stderr.
#include <google/protobuf/struct.pb.h>
#include <google/protobuf/util/json_util.h>
#include <sys/prctl.h>
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <memory>
#include <string>

#include "solver/mesh_cache.hpp"
#include "solver/run_spec.hpp"

namespace {

int usage(const char* msg) {
  if (msg) std::fprintf(stderr, "softshock-mesh: %s\n", msg);
  std::fprintf(
      stderr,
      "usage: softshock-mesh --spec SPEC.json --out FILE [--mesh-cache DIR]\n"
      "                      [--mesh-cache-bytes N] [--max-elements N] [--max-end-time S]\n"
      "                      [--mesh-root DIR]\n"
      "  the limits and the mesh root are the host's (softshockd's); the spec is\n"
      "  validated against them\n"
      "  writes the spec's mesh (before rim roughness) to FILE in the mesh cache's\n"
      "  entry format; softshockd runs it so that meshing can be cancelled\n"
      "exit codes: 0 done, 2 invalid spec or usage, 1 failure\n");
  return 2;
}

bool parse_count(const char* v, std::uint64_t max, std::uint64_t& out) {
  const char* end = v + std::strlen(v);
  const auto [ptr, ec] = std::from_chars(v, end, out);
  return ec == std::errc() && ptr == end && out <= max;
}

std::string report_json(const softshock::MeshingReport& report) {
  google::protobuf::Struct s;
  auto& f = *s.mutable_fields();
  f["meshing_time_s"].set_number_value(report.seconds);
  f["mesh_cache"].set_string_value(softshock::to_string(report.cache));
  f["warning"].set_string_value(report.warning);
  std::string out;
  (void)google::protobuf::util::MessageToJsonString(s, &out);
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  // The parent waits for this mesh; once it is gone nobody will read it.
  const pid_t parent = ::getppid();
  (void)::prctl(PR_SET_PDEATHSIG, SIGKILL);
  if (::getppid() != parent) return 1;  // it died before the line above took effect

  std::string spec_path, out_path, cache_dir;
  std::uint64_t cache_bytes = std::uint64_t{512} << 20;
  softshock::SpecLimits limits;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const char* v = i + 1 < argc ? argv[i + 1] : nullptr;
    if (a == "--help" || a == "-h") {
      usage(nullptr);
      return 0;
    }
    if (v == nullptr || *v == '\0') return usage((a + " needs a value").c_str());
    ++i;
    std::uint64_t n = 0;
    if (a == "--spec") {
      spec_path = v;
    } else if (a == "--out") {
      out_path = v;
    } else if (a == "--mesh-cache") {
      cache_dir = v;
    } else if (a == "--mesh-root") {
      limits.mesh_root = v;
    } else if (a == "--mesh-cache-bytes") {
      if (!parse_count(v, std::uint64_t{1} << 50, n)) return usage("--mesh-cache-bytes: bytes");
      cache_bytes = n;
    } else if (a == "--max-elements") {
      if (!parse_count(v, 2'000'000'000, n) || n == 0) {
        return usage("--max-elements: a number from 1 to 2000000000");
      }
      limits.max_elements = static_cast<int>(n);
    } else if (a == "--max-end-time") {
      char* end = nullptr;
      const double x = std::strtod(v, &end);
      if (end == v || *end != '\0' || !(x > 0) || !std::isfinite(x)) {
        return usage("--max-end-time: expects a number > 0");
      }
      limits.max_end_time_s = x;
    } else {
      return usage(("unknown argument '" + a + "'").c_str());
    }
  }
  if (spec_path.empty() || out_path.empty()) return usage("--spec and --out are required");

  try {
    std::unique_ptr<softshock::MeshCache> cache;
    if (!cache_dir.empty() && cache_bytes > 0) {
      cache = std::make_unique<softshock::MeshCache>(cache_dir, cache_bytes);
    }
    const auto spec = softshock::normalize_spec(softshock::read_spec_file(spec_path), limits);
    softshock::MeshingReport report;
    const softshock::Mesh mesh =
        softshock::smooth_mesh(spec.geometry(), limits, cache.get(), &report);
    softshock::write_mesh_entry(out_path, softshock::mesh_entry_material(spec.geometry()), mesh);
    std::cout << report_json(report) << std::endl;
  } catch (const softshock::SpecError& e) {
    std::fprintf(stderr, "softshock-mesh: invalid spec: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "softshock-mesh: %s\n", e.what());
    return 1;
  }
  return 0;
}
