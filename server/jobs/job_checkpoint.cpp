#include "server/jobs/job_checkpoint.hpp"

#include <cstdio>
#include <filesystem>
#include <memory>
#include <system_error>
#include <utility>

#include "server/byte_size.hpp"
#include "server/log.hpp"
#include "solver/io/checkpoint_folder.hpp"

namespace softshock::server {

namespace fs = std::filesystem;

std::string checkpoint_dir(const std::string& job_dir) {
  return (fs::path(job_dir) / "checkpoint").string();
}

std::optional<Checkpoint> load_job_checkpoint(const std::string& job_dir,
                                              const std::string& spec_json, const Mesh& mesh,
                                              int threads, std::string* why_not) {
  return load_checkpoint_folder(checkpoint_dir(job_dir), spec_json, mesh, threads, why_not);
}

std::vector<ResultWriter::Sealed> sealed_frames(const std::string& job_dir,
                                                const CheckpointHeader& header) {
  return checkpoint_segments(checkpoint_dir(job_dir), header);
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
  control.on_checkpoint = [this, &cancel](RunState&& state) {
    // Where the run stopped: a checkpoint only when the job will run again; else kept in memory
    // (moved, not copied), for a SUCCEEDED job's final state.
    if (state.stopped && cancel.reason() != StopReason::kShutdown) {
      final_state_ = std::move(state);
      return;
    }
    take(state);
  };
}

void JobCheckpointer::take(const RunState& state) {
  next_ = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                             std::chrono::duration<double>(options_.interval_s));
  const double bytes = checkpoint_state_bytes(state);
  if (options_.free_bytes) {
    if (const double free = options_.free_bytes(); free < bytes + options_.min_free_bytes) {
      log_warning("job ", options_.job_id, ": no checkpoint at step ", state.steps, ": ",
                  byte_size(free), " free, below the reserve plus the state's ", byte_size(bytes));
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
  const auto taken_at = Clock::now();
  const std::string id = options_.job_id;
  const double time_s = state.time_s;
  const int64_t steps = state.steps;
  ++taken_;
  const std::string state_path = (fs::path(dir) / kCheckpointStateFile).string();
  write_checkpoint_folder(
      writer_, dir, options_.spec_json, options_.mesh_fingerprint, state,
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
                      byte_size(size_ec ? 0.0 : static_cast<double>(size)).c_str(),
                      std::chrono::duration<double>(Clock::now() - taken_at).count());
        log_info("job ", id, ": ", line);
      });
}

}  // namespace softshock::server
