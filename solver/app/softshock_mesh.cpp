// softshock-mesh --spec SPEC.json --out FILE [--mesh-cache DIR [--mesh-cache-bytes N]]
//                [--max-elements N] [--max-end-time S] [--mesh-root DIR]
// Meshes one spec's geometry and writes the mesh (before rim roughness) to FILE in the mesh
// cache's entry format (solver/mesh_cache.hpp; temporary file + rename), through the cache
// when one is given, so a second job of the same geometry finds it there and concurrent
// builders of one geometry mesh it once (the cache's lock dies with a killed process).
//
// softshock-mesh --check FILE [--max-elements N] [--max-memory BYTES] [--max-cpu-seconds S]
//                [--tmp-dir DIR]
// Checks an uploaded mesh file as a spec's mesh_file is read (the counts its headers declare,
// Gmsh, the element limit) under resource limits it sets on itself first: address space, CPU
// time, no core file, the first process the kernel's OOM killer picks, its temporary files in
// DIR. Gmsh crashes or allocates without bound on some malformed files; here that ends this
// process, never softshockd (server/jobs/mesh_process.hpp).
//
// softshockd runs it as a child process for every Gmsh mesh: Gmsh cannot be interrupted
// inside the daemon, a child can be killed (server/jobs/mesh_process.hpp). It dies with the
// thread that started it (PR_SET_PDEATHSIG), so a daemon killed meanwhile leaves no orphan
// meshing on.
//
// stdout: {"meshing_time_s": S, "mesh_cache": "miss", "warning": "..."}; with --check
// {"nodes": N, "elements": E, "dimension": 2}. Exit codes: 0 done, 2 invalid spec, unusable mesh
// or usage, 1 failure; the reason is the last line on stderr.
#include <google/protobuf/struct.pb.h>
#include <google/protobuf/util/json_util.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iostream>
#include <memory>
#include <string>
#include <string_view>

#include "softshock/version.hpp"
#include "solver/gmsh_mesher.hpp"
#include "solver/mesh_cache.hpp"
#include "solver/msh_counts.hpp"
#include "solver/run_spec.hpp"

namespace {

int usage(const char* msg) {
  if (msg) std::fprintf(stderr, "softshock-mesh: %s\n", msg);
  std::fprintf(
      msg ? stderr : stdout,
      "usage: softshock-mesh --spec SPEC.json --out FILE [--mesh-cache DIR]\n"
      "                      [--mesh-cache-bytes N] [--max-elements N] [--max-end-time S]\n"
      "                      [--mesh-root DIR]\n"
      "  the limits and the mesh root are the host's (softshockd's); the spec is\n"
      "  validated against them\n"
      "  writes the spec's mesh (before rim roughness) to FILE in the mesh cache's\n"
      "  entry format; softshockd runs it so that meshing can be cancelled\n"
      "       softshock-mesh --check FILE [--max-elements N] [--max-memory BYTES]\n"
      "                      [--max-cpu-seconds S] [--tmp-dir DIR]\n"
      "  checks a mesh file under those limits; prints its node and element counts\n"
      "       softshock-mesh --help | --version\n"
      "exit codes: 0 done, 2 invalid spec, unusable mesh or usage, 1 failure\n");
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

#ifdef __SANITIZE_ADDRESS__
// In the sanitizer build (tests only) a crash in Gmsh on a hostile file must end this process by
// its signal, as in the release build, for the caller to report it as such; AddressSanitizer's own
// handler would turn it into exit status 1.
extern "C" const char* __asan_default_options() {
  return "handle_segv=0:handle_sigbus=0:handle_sigfpe=0:handle_abort=0";
}
#endif

// Limits this process sets on itself before it reads an untrusted file. A limit it cannot set
// is a failure: the file is not read unconfined.
void confine(std::uint64_t max_memory_bytes, std::uint64_t max_cpu_seconds) {
  auto set = [](int resource, rlim_t soft, rlim_t hard, const char* what) {
    const rlimit limit{soft, hard};
    if (::setrlimit(resource, &limit) != 0) {
      throw std::runtime_error(std::string("cannot limit ") + what + ": " + std::strerror(errno));
    }
  };
  set(RLIMIT_CORE, 0, 0, "core files");  // a crash on a 60 MB mesh must not write gigabytes
#ifndef __SANITIZE_ADDRESS__
  if (max_memory_bytes > 0) set(RLIMIT_AS, max_memory_bytes, max_memory_bytes, "address space");
#else
  // AddressSanitizer has reserved terabytes of shadow address space before main: an address-space
  // limit would fail every later mapping. The sanitizer build (tests only) runs without it.
  (void)max_memory_bytes;
#endif
  // SIGXCPU at the soft limit, SIGKILL one second later.
  if (max_cpu_seconds > 0) set(RLIMIT_CPU, max_cpu_seconds, max_cpu_seconds + 1, "CPU time");
  // If memory runs out anyway (a container's limit below the address space), the kernel's OOM
  // killer takes this process first, not the daemon; raising one's own score needs no privilege.
  std::ofstream("/proc/self/oom_score_adj") << 1000;
}

// The file's fault (exit 2), as opposed to this program's (a module that does not load: exit 1).
class UnusableMesh : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// --check: the mesh file as run_spec.cpp reads a spec's mesh_file.
int check_mesh_file(const std::string& path, int max_elements) {
  try {
    (void)softshock::check_msh_counts(path);  // before Gmsh is even loaded
  } catch (const std::runtime_error& e) {
    throw UnusableMesh(e.what());
  }
  softshock::Mesh mesh;
  try {
    mesh = softshock::read_gmsh_file(path);
  } catch (const std::runtime_error& e) {
    // read_gmsh_file names itself on everything the file causes (gmsh_mesher.cpp); the loader's
    // own failures (no module) do not.
    if (std::string_view(e.what()).starts_with("read_gmsh_file:")) throw UnusableMesh(e.what());
    throw;
  }
  if (static_cast<std::int64_t>(mesh.element_count()) > max_elements) {
    throw UnusableMesh("the mesh has " + std::to_string(mesh.element_count()) +
                       " elements, more than " + std::to_string(max_elements));
  }
  google::protobuf::Struct s;
  auto& f = *s.mutable_fields();
  f["nodes"].set_number_value(static_cast<double>(mesh.node_count()));
  f["elements"].set_number_value(static_cast<double>(mesh.element_count()));
  f["dimension"].set_number_value(mesh.dimension());  // 3 for a file of tetrahedra
  std::string out;
  (void)google::protobuf::util::MessageToJsonString(s, &out);
  std::cout << out << std::endl;
  return 0;
}

// --check: confined, then the file checked; the exit status says whose fault a failure is.
int run_check(const std::string& check_path, int max_elements, std::uint64_t max_memory,
              std::uint64_t max_cpu_seconds, const std::string& tmp_dir) {
  try {
    confine(max_memory, max_cpu_seconds);
    // Gmsh's private copy of the file (gmsh_mesher.cpp) goes here: the caller removes the
    // folder, so a crash leaves nothing behind in the system's temporary folder.
    if (!tmp_dir.empty() && ::setenv("TMPDIR", tmp_dir.c_str(), 1) != 0) {
      throw std::runtime_error("cannot set TMPDIR");
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "softshock-mesh: %s\n", e.what());
    return 1;
  }
  try {
    return check_mesh_file(check_path, max_elements);
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "softshock-mesh: unusable mesh: reading it needs more than %llu MiB\n",
                 static_cast<unsigned long long>(max_memory >> 20));
    return 2;
  } catch (const UnusableMesh& e) {
    // Gmsh turns an allocation failure into its own error text.
    if (std::string_view(e.what()).ends_with("std::bad_alloc")) {
      std::fprintf(stderr, "softshock-mesh: unusable mesh: reading it needs more than %llu MiB\n",
                   static_cast<unsigned long long>(max_memory >> 20));
      return 2;
    }
    std::fprintf(stderr, "softshock-mesh: unusable mesh: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "softshock-mesh: %s\n", e.what());
    return 1;
  }
}

}  // namespace

int main(int argc, char** argv) {
  // The parent waits for this mesh; once it is gone nobody will read it.
  const pid_t parent = ::getppid();
  (void)::prctl(PR_SET_PDEATHSIG, SIGKILL);
  if (::getppid() != parent) return 1;  // it died before the line above took effect

  std::string spec_path, out_path, cache_dir, check_path, tmp_dir;
  std::uint64_t cache_bytes = std::uint64_t{512} << 20;
  std::uint64_t max_memory = 0, max_cpu_seconds = 0;
  softshock::SpecLimits limits;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const char* v = i + 1 < argc ? argv[i + 1] : nullptr;
    if (a == "--help" || a == "-h") {
      usage(nullptr);
      return 0;
    }
    if (a == "--version") {
      std::printf("softshock-mesh %s\n", softshock::kVersion);
      return 0;
    }
    if (v == nullptr || *v == '\0') return usage((a + " needs a value").c_str());
    ++i;
    std::uint64_t n = 0;
    if (a == "--spec") {
      spec_path = v;
    } else if (a == "--check") {
      check_path = v;
    } else if (a == "--tmp-dir") {
      tmp_dir = v;
    } else if (a == "--max-memory") {
      if (!parse_count(v, std::uint64_t{1} << 50, n) || n < (std::uint64_t{64} << 20)) {
        return usage("--max-memory: bytes, at least 64 MiB");
      }
      max_memory = n;
    } else if (a == "--max-cpu-seconds") {
      if (!parse_count(v, 86400, n) || n == 0) return usage("--max-cpu-seconds: 1 to 86400");
      max_cpu_seconds = n;
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
  if (!check_path.empty()) {
    if (!spec_path.empty() || !out_path.empty()) return usage("--check takes no --spec or --out");
    // _exit: a throwaway process, which a hostile file may have left with Gmsh's state half
    // built; no exit handlers (nor a leak report in the sanitizer build) run over that state.
    const int code =
        run_check(check_path, limits.max_elements, max_memory, max_cpu_seconds, tmp_dir);
    std::fflush(nullptr);
    ::_exit(code);
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
