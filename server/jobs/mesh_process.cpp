#include "server/jobs/mesh_process.hpp"

#include <google/protobuf/struct.pb.h>
#include <google/protobuf/util/json_util.h>

#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "server/byte_size.hpp"
#include "server/jobs/process_io.hpp"
#include "solver/mesh_cache.hpp"

#ifndef SOFTSHOCK_MESHER_BUILD_PATH
#define SOFTSHOCK_MESHER_BUILD_PATH ""
#endif

namespace softshock::server {

namespace fs = std::filesystem;

namespace {

constexpr const char* kMesherName = "softshock-mesh";

std::string number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

// The last non-empty line: the child's reason, after whatever a library printed before it.
std::string last_line(const std::string& text) {
  std::size_t end = text.find_last_not_of("\r\n");
  if (end == std::string::npos) return {};
  const std::size_t begin = text.rfind('\n', end);
  return text.substr(begin == std::string::npos ? 0 : begin + 1,
                     end + 1 - (begin == std::string::npos ? 0 : begin + 1));
}

std::string strip_prefix(std::string s, const std::string& prefix) {
  if (s.rfind(prefix, 0) == 0) s.erase(0, prefix.size());
  return s;
}

// softshock-mesh's stdout report; a report that does not parse only loses the figures.
void read_report(const std::string& json, MeshingReport* report) {
  google::protobuf::Struct s;
  if (!google::protobuf::util::JsonStringToMessage(last_line(json), &s).ok()) return;
  const auto& f = s.fields();
  if (auto it = f.find("meshing_time_s"); it != f.end())
    report->seconds = it->second.number_value();
  if (auto it = f.find("warning"); it != f.end()) report->warning = it->second.string_value();
  if (auto it = f.find("mesh_cache"); it != f.end()) {
    const std::string& cache = it->second.string_value();
    for (auto o : {MeshCacheOutcome::kHit, MeshCacheOutcome::kMiss, MeshCacheOutcome::kReplaced}) {
      if (cache == to_string(o)) report->cache = o;
    }
  }
}

// The files handed over, removed whatever happens.
struct HandoverFiles {
  fs::path spec, mesh;
  ~HandoverFiles() {
    std::error_code ec;
    fs::remove(spec, ec);
    fs::remove(mesh, ec);
  }
};

}  // namespace

std::optional<Mesh> mesh_in_child(const MesherCommand& command, const v1::RunSpec& spec,
                                  const std::string& work_dir,
                                  const std::function<bool()>& should_stop, MeshingReport* report) {
  // Names ending in .tmp: JobRunner::remove_stale_files() clears what a killed daemon left.
  HandoverFiles files{fs::path(work_dir) / "meshing.spec.tmp",
                      fs::path(work_dir) / "meshing.mesh.tmp"};
  {
    std::ofstream out(files.spec, std::ios::trunc);
    out << spec_to_json(spec);
    if (!out.flush()) throw MeshingFailed("cannot write " + files.spec.string(), false);
  }
  std::vector<std::string> argv = {command.executable,
                                   "--spec",
                                   files.spec.string(),
                                   "--out",
                                   files.mesh.string(),
                                   "--max-elements",
                                   std::to_string(command.limits.max_elements),
                                   "--max-end-time",
                                   number(command.limits.max_end_time_s)};
  if (!command.limits.mesh_root.empty()) {
    argv.insert(argv.end(), {"--mesh-root", command.limits.mesh_root});
  }
  if (!command.cache_dir.empty() && command.cache_bytes > 0) {
    argv.insert(argv.end(), {"--mesh-cache", command.cache_dir, "--mesh-cache-bytes",
                             std::to_string(command.cache_bytes)});
  }
  const CommandResult r = run_command(argv, should_stop);
  if (r.stopped) return std::nullopt;
  if (r.status != 0) {
    std::string why = strip_prefix(last_line(r.err), std::string(kMesherName) + ": ");
    if (r.status == 2) {
      throw MeshingFailed(strip_prefix(why, "invalid spec: "), true);
    }
    if (r.signal != 0) {
      const char* name = ::sigdescr_np(r.signal);
      why = std::string(kMesherName) + " was killed by signal " + std::to_string(r.signal) + " (" +
            (name ? name : "?") + ")" + (why.empty() ? "" : " after: " + why);
    } else if (why.empty()) {
      why = std::string(kMesherName) + " exited with status " + std::to_string(r.status);
    }
    throw MeshingFailed(why, false);
  }
  bool unusable = false;
  auto mesh = read_mesh_entry(files.mesh.string(), mesh_entry_material(spec.geometry()), &unusable);
  if (!mesh) {
    throw MeshingFailed(std::string(kMesherName) + " succeeded but its mesh file is " +
                            (unusable ? "unusable" : "missing"),
                        false);
  }
  if (report) read_report(r.out, report);
  return mesh;
}

namespace {

// Every occurrence of `from` in `text` replaced by `to`.
void replace_all(std::string& text, const std::string& from, const std::string& to) {
  if (from.empty()) return;
  for (std::size_t at = text.find(from); at != std::string::npos;
       at = text.find(from, at + to.size())) {
    text.replace(at, from.size(), to);
  }
}

std::int64_t count_field(const google::protobuf::Struct& s, const char* name) {
  const auto it = s.fields().find(name);
  return it == s.fields().end() ? -1 : static_cast<std::int64_t>(it->second.number_value());
}

}  // namespace

MeshFileCheck check_mesh_file_in_child(const std::string& executable, const std::string& path,
                                       const std::string& display_name, const std::string& tmp_dir,
                                       const MeshCheckLimits& limits) {
  std::error_code ec;
  fs::create_directories(tmp_dir, ec);
  if (ec) throw MeshingFailed("cannot create the mesh checker's folder: " + ec.message(), false);
  struct RemoveDir {
    fs::path dir;
    ~RemoveDir() {
      std::error_code ignored;
      fs::remove_all(dir, ignored);
    }
  } remove_dir{tmp_dir};
  const std::vector<std::string> argv = {
      executable, "--check", path,
      // the caller's limit applies to the counts
      "--max-elements", "2000000000", "--max-memory", std::to_string(limits.max_memory_bytes),
      "--max-cpu-seconds", std::to_string(limits.max_cpu_seconds), "--tmp-dir", tmp_dir};
  const auto deadline =
      std::chrono::steady_clock::now() + std::chrono::duration<double>(limits.max_wall_seconds);
  const CommandResult r =
      run_command(argv, [&] { return std::chrono::steady_clock::now() >= deadline; });
  // The child names the file by the path it was given; the client knows it by its own name.
  std::string why = strip_prefix(last_line(r.err), std::string(kMesherName) + ": ");
  replace_all(why, path, display_name);
  replace_all(why, tmp_dir, "(temporary folder)");
  why = strip_prefix(strip_prefix(why, "unusable mesh: "),
                     "read_gmsh_file: '" + display_name + "': ");
  if (r.stopped) {
    throw MeshingFailed("checking the mesh took longer than " + number(limits.max_wall_seconds) +
                            " s (the daemon's limit)",
                        true);
  }
  if (r.status == 0) {
    google::protobuf::Struct s;
    if (google::protobuf::util::JsonStringToMessage(last_line(r.out), &s).ok()) {
      MeshFileCheck check{count_field(s, "nodes"), count_field(s, "elements"),
                          static_cast<int>(count_field(s, "dimension"))};
      if (check.nodes > 0 && check.elements > 0) return check;
    }
    throw MeshingFailed(std::string(kMesherName) + " --check printed no counts", false);
  }
  if (r.status == 2) throw MeshingFailed(why, true);
  if (r.signal == SIGXCPU || r.signal == SIGKILL) {
    // SIGKILL: the CPU limit's hard stop, or the kernel's OOM killer.
    throw MeshingFailed("checking the mesh ran out of its limits (" +
                            std::to_string(limits.max_cpu_seconds) + " s of CPU time, " +
                            byte_size(limits.max_memory_bytes) + " of memory)",
                        true);
  }
  if (r.signal != 0) {
    const char* name = ::sigdescr_np(r.signal);
    throw MeshingFailed("Gmsh crashed reading it (signal " + std::to_string(r.signal) + ", " +
                            (name ? name : "?") + ")",
                        true);
  }
  throw MeshingFailed(why.empty() ? std::string(kMesherName) + " --check exited with status " +
                                        std::to_string(r.status)
                                  : why,
                      false);
}

MeshValidator mesh_validator_in_child(std::string executable, MeshCheckLimits limits) {
  return [executable = std::move(executable), limits](
             const std::string& path, const std::string& display_name,
             const std::string& scratch_dir) -> MeshCounts {
    if (executable.empty()) {
      throw std::runtime_error(std::string(kMesherName) +
                               " is not installed beside softshockd: uploaded meshes cannot be "
                               "checked, so none are accepted");
    }
    try {
      const MeshFileCheck check =
          check_mesh_file_in_child(executable, path, display_name, scratch_dir, limits);
      return {check.nodes, check.elements};
    } catch (const MeshingFailed& e) {
      if (!e.invalid_spec()) throw;
      throw SpecError("data", "'" + display_name + "' is not a usable Gmsh mesh: " + e.what());
    }
  };
}

std::string find_mesher() {
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const fs::path beside = exe.parent_path() / kMesherName;
    if (fs::exists(beside, ec)) return beside.string();
  }
  if (*SOFTSHOCK_MESHER_BUILD_PATH != '\0' && fs::exists(SOFTSHOCK_MESHER_BUILD_PATH, ec)) {
    return SOFTSHOCK_MESHER_BUILD_PATH;
  }
  return {};
}

}  // namespace softshock::server
