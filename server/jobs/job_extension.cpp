#include "server/jobs/job_extension.hpp"

#include <filesystem>
#include <stdexcept>

#include "server/jobs/job_checkpoint.hpp"
#include "softshock/version.hpp"
#include "solver/io/result_file.hpp"
#include "solver/run_spec.hpp"

namespace softshock::server {

namespace fs = std::filesystem;

namespace {

constexpr const char* kParentFrames = "parent_frames.h5";

// The spec with its end time replaced: what the parent ran, asked of a later end time.
std::string with_end_time(const std::string& spec_json, double end_time_s) {
  v1::RunSpec spec = parse_spec_json(spec_json, SpecJson::kStored);
  spec.mutable_run()->set_end_time(end_time_s);
  return spec_to_json(spec);
}

}  // namespace

std::string final_state_path(const std::string& job_dir) {
  return (fs::path(job_dir) / "final_state.ckpt").string();
}

void save_final_state(const std::string& job_dir, const std::string& spec_json,
                      const std::string& mesh_fingerprint, const RunState& stopped,
                      const std::string& result_h5) {
  if (!stopped.stopped) throw std::runtime_error("not the state where the run stopped");
  Checkpoint c;
  c.header.solver_revision = kSolverRevision;
  c.header.solver_version = SOFTSHOCK_VERSION;
  c.header.spec_json = spec_json;
  c.header.mesh_fingerprint = mesh_fingerprint;
  // The frames the state has written; a frame off the output schedule at the end time (written
  // after the stop) is not the continued run's.
  const ResultReader reader(result_h5);
  const auto& times = reader.info().frame_times;
  if (times.size() < stopped.frames_written)
    throw std::runtime_error("the result has fewer frames than the state has written");
  c.header.frame_times.assign(times.begin(),
                              times.begin() + static_cast<std::ptrdiff_t>(stopped.frames_written));
  if (stopped.frames_written > 0)
    c.header.segments.push_back({kParentFrames, stopped.frames_written});
  c.state = stopped;
  write_checkpoint(final_state_path(job_dir), c);  // temporary file + rename
}

std::optional<Checkpoint> load_parent_state(const std::string& parent_dir,
                                            const std::string& job_dir,
                                            const std::string& spec_json, const Mesh& mesh,
                                            int threads, std::string* why_not) {
  auto refuse = [&](const std::string& why) -> std::optional<Checkpoint> {
    if (why_not) *why_not = why;
    return std::nullopt;
  };
  const std::string path = final_state_path(parent_dir);
  std::error_code ec;
  if (!fs::exists(path, ec)) return refuse("the parent kept no final state");
  Checkpoint c;
  try {
    c = read_checkpoint(path);
  } catch (const std::exception& e) {
    return refuse(e.what());
  }
  try {
    const double end_time = parse_spec_json(spec_json, SpecJson::kStored).run().end_time();
    if (!(end_time > c.state.time_s)) return refuse("the end time is not after the parent's");
    if (with_end_time(c.header.spec_json, end_time) != spec_json)
      return refuse("the spec differs from the parent's in more than run.end_time");
  } catch (const std::exception& e) {
    return refuse(std::string("spec: ") + e.what());
  }
  if (c.header.mesh_fingerprint != mesh_fingerprint(mesh)) return refuse("another mesh");
  if (c.state.threads != threads) {
    return refuse("the parent ran with " + std::to_string(c.state.threads) +
                  " solver thread(s), the daemon now runs " + std::to_string(threads));
  }
  if (!c.header.segments.empty()) {
    const fs::path folder = checkpoint_dir(job_dir);
    fs::create_directories(folder, ec);
    const fs::path from = fs::path(parent_dir) / "result.h5", to = folder / kParentFrames;
    fs::remove(to, ec);
    fs::create_hard_link(from, to, ec);
    if (ec) {  // another file system, or no hard links: a copy
      ec.clear();
      fs::copy_file(from, to, ec);
      if (ec) return refuse("cannot link or copy the parent's result: " + ec.message());
    }
  }
  return c;
}

}  // namespace softshock::server
