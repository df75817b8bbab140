#include "server/jobs/job_checkpoint.hpp"

#include <cstdio>
#include <filesystem>
#include <memory>
#include <system_error>
#include <utility>

#include "server/log.hpp"
#include "softshock/version.hpp"
#include "solver/run_summary.hpp"

namespace softshock::server {

namespace fs = std::filesystem;

namespace {

constexpr const char* kStateFile = "state.ckpt";

std::string megabytes(double bytes) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1f MB", bytes / 1e6);
  return buf;
}

// Bytes the state takes in a checkpoint file, near enough for the free-space check.
double state_bytes(const RunState& s) {
  double bytes = 0;
  for (const auto& a : s.arrays) bytes += 8.0 * a.f64.size() + 4.0 * a.f32.size();
  for (const auto& column : s.history.columns()) bytes += 8.0 * column.second->size();
  for (const auto& row : s.history.modes) bytes += 8.0 * row.size();
  for (const auto& row : s.history.modes_z_mean) bytes += 8.0 * row.size();
  return bytes;
}

}  // namespace

std::string checkpoint_dir(const std::string& job_dir) {
  return (fs::path(job_dir) / "checkpoint").string();
}

std::optional<Checkpoint> load_job_checkpoint(const std::string& job_dir,
                                              const std::string& spec_json, const Mesh& mesh,
                                              int threads, std::string* why_not) {
  const fs::path path = fs::path(checkpoint_dir(job_dir)) / kStateFile;
  std::error_code ec;
  if (!fs::exists(path, ec)) return std::nullopt;
  auto refuse = [&](const std::string& why) -> std::optional<Checkpoint> {
    if (why_not) *why_not = why;
    return std::nullopt;
  };
  Checkpoint c;
  try {
    c = read_checkpoint(path.string());
  } catch (const std::exception& e) {
    return refuse(e.what());
  }
  if (c.header.spec_json != spec_json) return refuse("taken for another spec");
  if (c.header.mesh_fingerprint != mesh_fingerprint(mesh)) return refuse("taken on another mesh");
  if (c.state.threads != threads) {
    return refuse("taken with " + std::to_string(c.state.threads) +
                  " solver thread(s), the daemon now runs " + std::to_string(threads) +
                  " (the sums' order would differ)");
  }
  for (const auto& sealed : sealed_frames(job_dir, c.header)) {
    if (!fs::exists(sealed.path, ec)) return refuse("its frame file " + sealed.path + " is gone");
  }
  return c;
}

std::vector<ResultWriter::Sealed> sealed_frames(const std::string& job_dir,
                                                const CheckpointHeader& header) {
  std::vector<ResultWriter::Sealed> out;
  for (const auto& s : header.segments)
    out.push_back({(fs::path(checkpoint_dir(job_dir)) / s.file).string(), s.frames});
  return out;
}

void remove_job_checkpoint(const std::string& job_dir) {
  std::error_code ec;
  fs::remove_all(checkpoint_dir(job_dir), ec);
  if (ec) log_warning("cannot remove ", checkpoint_dir(job_dir), ": ", ec.message());
}

JobCheckpointer::JobCheckpointer(Options options, AsyncResultWriter& writer)
    : options_(std::move(options)), writer_(writer) {
  next_ = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                             std::chrono::duration<double>(std::max(0.0, options_.interval_s)));
}

void JobCheckpointer::attach(RunControl& control, const CancelToken& cancel) {
  if (options_.interval_s > 0) {
    control.checkpoint_due = [this](const Progress&) { return Clock::now() >= next_; };
  }
  control.checkpoint_at_stop = true;
  control.on_checkpoint = [this, &cancel](const RunState& state) {
    // Where the run stopped: a checkpoint only when the job will run again; else kept in memory,
    // for a SUCCEEDED job's final state.
    if (state.stopped && cancel.reason() != StopReason::kShutdown) {
      final_state_ = state;
      return;
    }
    take(state);
  };
}

void JobCheckpointer::take(const RunState& state) {
  next_ = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                             std::chrono::duration<double>(options_.interval_s));
  const double bytes = state_bytes(state);
  if (options_.free_bytes) {
    if (const double free = options_.free_bytes(); free < bytes + options_.min_free_bytes) {
      log_warning("job ", options_.job_id, ": no checkpoint at step ", state.steps, ": ",
                  megabytes(free), " free, below the reserve plus the state's ", megabytes(bytes));
      return;
    }
  }
  const std::string dir = checkpoint_dir(options_.job_dir);
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) {
    log_warning("job ", options_.job_id, ": no checkpoint: cannot create ", dir, ": ",
                ec.message());
    return;
  }
  Checkpoint c;
  c.header.solver_revision = kSolverRevision;
  c.header.solver_version = SOFTSHOCK_VERSION;
  c.header.spec_json = options_.spec_json;
  c.header.mesh_fingerprint = options_.mesh_fingerprint;
  c.state = state;
  // Named by step: a continued run's files never take the name of one its checkpoint lists.
  char name[48];
  std::snprintf(name, sizeof name, "frames_%012lld.h5", static_cast<long long>(state.steps));
  const std::string state_path = (fs::path(dir) / kStateFile).string();
  const auto taken_at = Clock::now();
  const std::string id = options_.job_id;
  const double time_s = state.time_s;
  const int64_t steps = state.steps;
  ++taken_;
  writer_.checkpoint(
      std::move(c), (fs::path(dir) / name).string(), state_path,
      [id, state_path, taken_at, time_s, steps](const std::string& error) {
        if (!error.empty()) {
          log_warning("job ", id, ": checkpoint at step ", steps,
                      " not written (the previous one stays): ", error);
          return;
        }
        std::error_code size_ec;
        const auto size = fs::file_size(state_path, size_ec);
        char line[160];
        std::snprintf(line, sizeof line,
                      "checkpoint at t = %.6g s, step %lld: %s, written %.3f s after it was taken",
                      time_s, static_cast<long long>(steps),
                      megabytes(size_ec ? 0.0 : static_cast<double>(size)).c_str(),
                      std::chrono::duration<double>(Clock::now() - taken_at).count());
        log_info("job ", id, ": ", line);
      });
}

}  // namespace softshock::server
