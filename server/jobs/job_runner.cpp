#include "server/jobs/job_runner.hpp"

#include <google/protobuf/struct.pb.h>
#include <google/protobuf/util/json_util.h>
#include <sys/statvfs.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <optional>
#include <utility>

#include "server/byte_size.hpp"
#include "server/jobs/job_checkpoint.hpp"
#include "server/jobs/job_extension.hpp"
#include "server/jobs/mesh_process.hpp"
#include "server/log.hpp"
#include "server/store/resource_exhausted.hpp"
#include "softshock/version.hpp"
#include "solver/io/async_result_writer.hpp"
#include "solver/io/result_file.hpp"
#include "solver/run_summary.hpp"
#include "solver/simulation.hpp"
#include "solver/summary_figures.hpp"

namespace softshock::server {

namespace fs = std::filesystem;

namespace {

// Seconds in messages: "8e-09 s", not std::to_string's "0.000000 s".
std::string seconds(double s) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g s", s);
  return buf;
}

JobProgressRecord to_record(const Progress& p) {
  JobProgressRecord r;
  r.fraction = std::clamp(p.fraction(), 0.0, 1.0);
  r.simulated_time_s = p.time_s;
  r.steps = p.steps;
  r.dt_s = p.dt_s;
  return r;
}

// A number of the summary JSON; null (written for non-finite values) reads back as NaN.
double number_of(const google::protobuf::Value& v) {
  return v.has_number_value() ? v.number_value() : NAN;
}

}  // namespace

v1::RunSpec parse_stored_spec(const std::string& json) {
  return parse_spec_json(json, SpecJson::kStored);
}

RunSummary parse_summary_json(const std::string& json) {
  google::protobuf::Struct s;
  if (!google::protobuf::util::JsonStringToMessage(json, &s).ok()) {
    throw std::runtime_error("summary JSON does not parse");
  }
  const auto& top = s.fields();
  const auto groups = top.find("groups");
  RunSummary r;
  // Absent in results written before revisions were recorded: 0, never equal to a live one.
  r.solver_revision = 0;
  // Damage figures are written only for a run with damage.
  r.damage = top.find("damage_onset_s") != top.end();
  for (const auto& figure : summary_figures()) {
    if (figure.has(kDerived) || figure.has(kNotInJson)) continue;
    if (figure.has(kOnlyDamage) && !r.damage) continue;
    if (figure.has(kInGroups) && groups == top.end()) continue;
    const auto& fields = figure.has(kInGroups) ? groups->second.struct_value().fields() : top;
    const auto it = fields.find(figure.name);
    // Absent: an optional figure (one added later, or written only for some runs) keeps
    // RunSummary's default; a figure every summary has reads as not known (NaN, 0, empty).
    if (it == fields.end() && (figure.has(kOptional) || figure.has(kOnly3D))) continue;
    const google::protobuf::Value none;
    const google::protobuf::Value& v = it == fields.end() ? none : it->second;
    switch (figure.type) {
      case FigureType::kText:
        figure.text_ref(r) = v.string_value();
        break;
      case FigureType::kSeries: {
        auto& out = figure.series_ref(r);
        out.clear();
        for (const auto& x : v.list_value().values()) out.push_back(number_of(x));
        break;
      }
      case FigureType::kInteger:
      case FigureType::kFlag:
      case FigureType::kReal:
        figure.set(r, number_of(v));  // integers: anything but 0..2^53 reads as 0
        break;
    }
  }
  return r;
}

StoredSummary stored_summary_from_result(const std::string& h5_path, bool* complete) {
  ResultReader reader(h5_path);
  if (complete) *complete = reader.info().complete;
  History history;
  history.time = reader.series("time");
  history.abar = reader.series("abar");
  std::size_t rows = 0, cols = 0;
  const std::vector<double> amplitudes = reader.mode_amplitudes(rows, cols);
  // /modes has its own time axis; make_stored_summary pairs history.time[k] with modes[k].
  const std::vector<double> mode_times = reader.mode_times();
  History modes_history;
  modes_history.time = mode_times;
  for (std::size_t k = 0; k < rows; ++k) {
    modes_history.modes.emplace_back(amplitudes.begin() + k * cols,
                                     amplitudes.begin() + (k + 1) * cols);
  }
  const RunSummary summary = parse_summary_json(reader.info().summary_json);
  StoredSummary stored = make_stored_summary(summary, modes_history);
  const StoredSummary abar = make_stored_summary(summary, history);
  stored.abar_times = abar.abar_times;
  stored.abar_values = abar.abar_values;
  return stored;
}

// The solver names its causes as the job reasons do (reason::kElementInversion, ...).
std::string failure_reason(FailureKind kind) {
  const std::string name = failure_name(kind);
  return name.empty() ? reason::kInternal : name;
}

std::string failure_reason(const std::string& summary_failure) {
  for (const FailureKind kind : {FailureKind::kElementInversion, FailureKind::kNonFinite,
                                 FailureKind::kTimeStepCollapse, FailureKind::kMeshDistortion}) {
    if (summary_failure == failure_name(kind)) return failure_reason(kind);
  }
  return "";
}

StoredSummary make_stored_summary(const RunSummary& summary, const History& history,
                                  double interval_s, int max_modes, std::size_t max_abar_samples) {
  StoredSummary out;
  out.summary = summary;
  const std::size_t samples = std::min(history.time.size(), history.modes.size());
  std::size_t columns = samples == 0 ? 0 : history.modes[0].size();
  for (std::size_t k = 0; k < samples; ++k) columns = std::min(columns, history.modes[k].size());
  out.mode_count = static_cast<int>(std::min<std::size_t>(columns, max_modes));
  double next_time = -1e300;
  for (std::size_t k = 0; k < samples; ++k) {
    const bool last = k + 1 == samples;
    // Half a history interval of slack keeps a sample that lands a rounding error early.
    if (history.time[k] + 1e-15 < next_time && !last) continue;
    out.mode_times.push_back(history.time[k]);
    for (int m = 0; m < out.mode_count; ++m) out.mode_amplitudes.push_back(history.modes[k][m]);
    next_time = history.time[k] + interval_s;
  }
  // A-bar(t) for grid reductions ("A-bar at t-bar"): every history sample up to ~1000, then
  // every k-th (the last one always kept).
  const std::size_t n = std::min(history.time.size(), history.abar.size());
  const std::size_t stride =
      (n + max_abar_samples - 1) / std::max<std::size_t>(1, max_abar_samples);
  for (std::size_t k = 0; k < n; ++k) {
    if (k % std::max<std::size_t>(1, stride) != 0 && k + 1 != n) continue;
    out.abar_times.push_back(history.time[k]);
    out.abar_values.push_back(history.abar[k]);
  }
  return out;
}

JobRunner::JobRunner(RunnerConfig config, Catalogue& catalogue, JobEvents& events)
    : config_(std::move(config)), catalogue_(catalogue), events_(events) {
  config_.limits.mesh_root = meshes_dir();  // never a client-chosen path elsewhere
  if (config_.mesh_cache_bytes > 0) {
    try {
      mesh_cache_ = std::make_unique<MeshCache>(mesh_cache_dir(), config_.mesh_cache_bytes);
    } catch (const std::exception& e) {
      log_warning("no mesh cache (every job meshes): ", e.what());
    }
  }
}

std::optional<Mesh> JobRunner::mesh_job(const std::string& id, const v1::RunSpec& spec,
                                        const std::function<bool()>& should_stop,
                                        MeshingReport* report) {
  const auto& geometry = spec.geometry();
  if (config_.mesher.empty() || !meshes_with_gmsh(geometry)) {
    // Ring meshes and strips take milliseconds, with checks the solver owns: no child needed.
    return smooth_mesh(geometry, config_.limits, mesh_cache_.get(), report);
  }
  if (const auto material = mesh_cache_ ? mesh_key_material(geometry) : std::nullopt) {
    const auto started = std::chrono::steady_clock::now();
    if (auto cached = mesh_cache_->load(mesh_cache_key(*material), *material)) {
      if (report) {
        report->cache = MeshCacheOutcome::kHit;
        report->seconds =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
      }
      return cached;
    }
  }
  MesherCommand command;
  command.executable = config_.mesher;
  command.limits = config_.limits;
  if (mesh_cache_) {
    command.cache_dir = mesh_cache_->dir();
    command.cache_bytes = mesh_cache_->max_bytes();
  }
  const std::string dir = job_dir(id);
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw std::runtime_error("cannot create " + dir + ": " + ec.message());
  return mesh_in_child(command, spec, dir, should_stop, report);
}

std::string JobRunner::mesh_cache_dir() const {
  return (fs::path(config_.data_dir) / "cache" / "meshes").string();
}

double JobRunner::free_bytes() const {
  if (config_.free_bytes) return config_.free_bytes(config_.data_dir);
  struct statvfs st {};
  if (::statvfs(config_.data_dir.c_str(), &st) != 0) return INFINITY;  // unknown: do not block
  return static_cast<double>(st.f_bavail) * static_cast<double>(st.f_frsize);
}

void JobRunner::require_free_space() const {
  if (const double free = free_bytes(); free < config_.min_free_bytes) {
    throw ResourceExhausted("the daemon's disk has " + byte_size(free) +
                            " free, below its reserve of " + byte_size(config_.min_free_bytes) +
                            " (min-free-bytes): delete jobs or meshes to make room");
  }
}

std::string JobRunner::job_dir(const std::string& id) const {
  return (fs::path(config_.data_dir) / "jobs" / id).string();
}

std::string JobRunner::meshes_dir() const {
  return (fs::path(config_.data_dir) / "meshes").string();
}

void JobRunner::remove_stale_files(const std::string& id) const {
  std::error_code ec;
  const fs::path dir = job_dir(id);
  if (!fs::exists(dir, ec)) return;
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    const std::string name = entry.path().filename().string();
    // result.h5.tmp, meshing.mesh.tmp, and a killed writer's meshing.mesh.tmp.<writer>.<n>
    if ((name.size() >= 4 && name.compare(name.size() - 4, 4, ".tmp") == 0) ||
        name.find(".tmp.") != std::string::npos) {
      fs::remove(entry.path(), ec);
    }
  }
  // A checkpoint half-written when the process died (the last whole one stays).
  fs::remove(fs::path(checkpoint_dir(dir.string())) / "state.ckpt.tmp", ec);
}

std::string JobRunner::link_result(const std::string& source_result_path,
                                   const std::string& id) const {
  return link_result_files(source_result_path, job_dir(id));
}

bool JobRunner::reuse_identical(const JobRecord& job) const {
  auto source = catalogue_.find_reusable(job.spec_hash, job.id);
  if (!source) return false;
  try {
    const std::string path = link_result(source->result_path, job.id);
    if (!catalogue_.complete_reused(job.id, source->id, path, now_us())) return true;  // gone
  } catch (const std::exception& e) {
    // Not fatal: the job simply runs itself.
    log_warning("job ", job.id, ": cannot reuse the result of ", source->id, ": ", e.what());
    return false;
  }
  log_info("job ", job.id, " SUCCEEDED reusing the result of identical job ", source->id);
  events_.forget(job.id);  // wakes watchers
  return true;
}

void JobRunner::run(const std::string& id, CancelToken& cancel) {
  try {
    run_job(id, cancel);
  } catch (const std::exception& e) {
    fail_running(id, std::string("internal error: ") + e.what());
  } catch (...) {
    fail_running(id, "internal error: unknown exception");
  }
}

// No job is left RUNNING by an error of ours: whatever threw, the job is recorded FAILED with
// the reason (if the catalogue can take a write at all; if not, start-up recovery requeues it).
void JobRunner::fail_running(const std::string& id, const std::string& error) {
  log_error("job ", id, ": ", error);
  try {
    if (auto job = catalogue_.get(id); job && job->state == JobState::kRunning) {
      if (catalogue_.finish(id, job->attempt, JobState::kFailed, reason::kInternal, error, "",
                            job->progress, nullptr, now_us())) {
        log_info("job ", id, " FAILED ", reason::kInternal, ": ", error);
      }
    }
  } catch (const std::exception& e) {
    log_error("job ", id,
              ": cannot record the failure either (stays RUNNING until the next "
              "start-up requeues it): ",
              e.what());
  }
  events_.forget(id);  // wakes watchers
}

void JobRunner::run_job(const std::string& id, CancelToken& cancel) {
  using Clock = std::chrono::steady_clock;
  const auto started = Clock::now();
  // An identical run may have finished while this one waited in the queue.
  if (auto queued = catalogue_.get(id); queued && queued->state == JobState::kQueued &&
                                        queued->reuse_result && reuse_identical(*queued)) {
    return;
  }
  auto job = catalogue_.start(id, now_us());
  if (!job) return;  // cancelled or deleted while queued: nothing to do
  events_.set_progress(id, {});
  log_info("job ", id, " started (attempt ", job->attempt, ")");

  JobProgressRecord last_progress;
  auto finish = [&](JobState state, const std::string& why, const std::string& error,
                    const std::string& result_path, const StoredSummary* summary) {
    bool ok = false;
    try {
      ok = catalogue_.finish(id, job->attempt, state, why, error, result_path, last_progress,
                             summary, now_us());
    } catch (const std::exception& e) {
      // The outcome could not be recorded (catalogue error, disk full): a plain FAILED needs
      // no summary, so it may still commit.
      fail_running(id, "recording the " + std::string(to_string(state)) + " outcome: " + e.what());
      return;
    }
    if (!ok) {
      log_warning("job ", id, ": ", to_string(state), " not recorded (job changed meanwhile)");
    } else if (state == JobState::kSucceeded) {
      log_info("job ", id, " SUCCEEDED in ",
               seconds(std::chrono::duration<double>(Clock::now() - started).count()));
    } else {
      log_info("job ", id, " ", to_string(state), " ", why, ": ", error);
    }
    events_.forget(id);  // wakes watchers; no live progress once it stops
  };
  auto requeue = [&](const std::string& why) {
    if (catalogue_.requeue(id, job->attempt, why, now_us())) {
      log_info("job ", id, " requeued (", why, ")");
    }
    events_.forget(id);  // wakes watchers; no live progress once it stops
  };

  // Setup: spec, mesh, writer. Spec problems here mean the limits changed since submission or
  // the mesh file is unusable: the job fails, it is not retried.
  v1::RunSpec spec;
  Problem problem;
  SolverOptions options;
  MeshingReport meshing;
  ResourceEstimate estimate;
  // Meshing in a child (Gmsh) is stopped by a cancel or the wall-time limit within a poll
  // interval; in-process meshing is not, and the stop takes effect once it returns.
  auto stop_meshing = [&] {
    if (config_.max_wall_time_s > 0 &&
        std::chrono::duration<double>(Clock::now() - started).count() > config_.max_wall_time_s) {
      cancel.request(StopReason::kWallTime);
    }
    return cancel.requested();
  };
  try {
    // limits.mesh_root confines geometry.mesh_file to DATA/meshes/ (solver/mesh_file_path.hpp).
    spec = normalize_spec(parse_stored_spec(job->spec_json), config_.limits);
    auto mesh = mesh_job(id, spec, stop_meshing, &meshing);
    if (mesh) {
      problem = make_problem_with_mesh(spec, std::move(*mesh), config_.limits);
      if (!meshing.warning.empty()) log_warning("job ", id, ": mesh not cached: ", meshing.warning);
      // Again with the real mesh (a mesh_file is first known here) and today's limits.
      estimate = estimate_mesh_resources(spec, problem.mesh);
      check_admission(spec, estimate, config_.admission);
      options = make_options(spec);
      options.threads = std::max(1, config_.solver_threads);
    }
  } catch (const SpecError& e) {
    finish(JobState::kFailed, reason::kInvalidSpec, e.what(), "", nullptr);
    return;
  } catch (const MeshingFailed& e) {
    finish(JobState::kFailed, e.invalid_spec() ? reason::kInvalidSpec : reason::kInternal,
           e.invalid_spec() ? e.what() : std::string("meshing: ") + e.what(), "", nullptr);
    return;
  } catch (const std::exception& e) {
    finish(JobState::kFailed, reason::kInternal, std::string("setup: ") + e.what(), "", nullptr);
    return;
  }
  // A stop requested while meshing (the child was killed, or in-process meshing returned).
  if (cancel.requested()) {
    switch (cancel.reason()) {
      case StopReason::kShutdown:
        requeue(reason::kShutdown);
        return;
      case StopReason::kWallTime:
        finish(JobState::kFailed, reason::kWallTimeExceeded,
               "wall time limit of " + seconds(config_.max_wall_time_s) + " reached while meshing",
               "", nullptr);
        return;
      default:
        finish(JobState::kCancelled, reason::kCancelledByUser, "cancelled by user while meshing",
               "", nullptr);
        return;
    }
  }

  const std::string dir = job_dir(id);
  if (const double free = free_bytes(); free < estimate.disk_bytes + config_.min_free_bytes) {
    finish(JobState::kFailed, reason::kDiskFull,
           "the data folder has " + byte_size(free) +
               " free; this job's result and the state it keeps need about " +
               byte_size(estimate.disk_bytes) + " above a reserve of " +
               byte_size(config_.min_free_bytes),
           "", nullptr);
    return;
  }
  std::unique_ptr<AsyncResultWriter> writer;
  const std::string spec_json = spec_to_json(spec);
  // An earlier attempt's last checkpoint, when this run can continue from it.
  std::optional<Checkpoint> resume;
  try {
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (ec) throw std::runtime_error("cannot create " + dir + ": " + ec.message());
    // A previous attempt's files (interrupted, or a partial result) are superseded.
    for (const char* name : {"result.h5", "result.xdmf"}) fs::remove(fs::path(dir) / name, ec);
    remove_stale_files(id);
    std::string why_not;
    resume = load_job_checkpoint(dir, spec_json, problem.mesh, options.threads, &why_not);
    if (!why_not.empty()) log_warning("job ", id, ": checkpoint not used: ", why_not);
    if (resume) {
      try {
        writer = std::make_unique<AsyncResultWriter>(
            dir, problem.mesh, spec_json, SOFTSHOCK_VERSION, sealed_frames(dir, resume->header),
            resume->header.frame_times);
        log_info("job ", id,
                 " continues from its checkpoint at t = ", seconds(resume->state.time_s), ", step ",
                 resume->state.steps);
      } catch (const std::exception& e) {
        log_warning("job ", id, ": checkpoint not used: ", e.what());
        resume.reset();
      }
    }
    if (!resume) remove_job_checkpoint(dir);   // an older checkpoint's files go
    if (!resume && !job->parent_id.empty()) {  // ExtendJob: from where the parent stopped
      why_not.clear();
      resume = load_parent_state(job_dir(job->parent_id), dir, spec_json, problem.mesh,
                                 options.threads, &why_not);
      try {
        if (resume) {
          writer = std::make_unique<AsyncResultWriter>(
              dir, problem.mesh, spec_json, SOFTSHOCK_VERSION, sealed_frames(dir, resume->header),
              resume->header.frame_times);
          log_info("job ", id, " continues job ", job->parent_id,
                   " from its final state at t = ", seconds(resume->state.time_s), ", step ",
                   resume->state.steps);
        }
      } catch (const std::exception& e) {
        why_not = e.what();
        resume.reset();
      }
      if (!resume) {
        log_warning("job ", id, ": runs from t = 0, job ", job->parent_id,
                    "'s final state not used: ", why_not);
        remove_job_checkpoint(dir);
      }
    }
    if (!resume) {
      writer = std::make_unique<AsyncResultWriter>(dir, problem.mesh, spec_json, SOFTSHOCK_VERSION);
    }
  } catch (const std::exception& e) {
    finish(JobState::kFailed, reason::kInternal, std::string("result file: ") + e.what(), "",
           nullptr);
    return;
  }

  // Run. Callbacks come from the solver thread between steps: keep them cheap.
  std::string io_error;
  const auto progress_every = std::chrono::duration<double>(config_.progress_interval_s);
  auto next_publish = Clock::now();
  RunControl control;
  control.cancel = cancel.flag();
  control.on_progress = [&](const Progress& p) {
    last_progress = to_record(p);
    last_progress.elements = static_cast<int64_t>(problem.mesh.element_count());
    const auto now = Clock::now();
    if (now < next_publish) return;
    next_publish = now + std::chrono::duration_cast<Clock::duration>(progress_every);
    events_.set_progress(id, last_progress);
    if (config_.max_wall_time_s > 0 &&
        std::chrono::duration<double>(now - started).count() > config_.max_wall_time_s) {
      cancel.request(StopReason::kWallTime);
    }
  };
  // A frame is about as large as the estimate's share per frame; it is not written when it
  // would eat into the reserve (the catalogue must still be able to commit the outcome).
  const double frame_bytes =
      problem.mesh.element_count() * 56.0 + 64.0 * static_cast<double>(problem.mesh.x.size());
  bool disk_full = false;
  control.on_frame = [&](FieldFrame frame) {
    if (!io_error.empty()) return;
    if (const double free = free_bytes(); free < frame_bytes + config_.min_free_bytes) {
      disk_full = true;
      io_error = "the data folder has " + byte_size(free) + " free, below the reserve of " +
                 byte_size(config_.min_free_bytes) + " plus a frame";
      cancel.request(StopReason::kInternal);
      return;
    }
    try {
      writer->write_frame(std::move(frame));
    } catch (const std::exception& e) {
      io_error = e.what();
      cancel.request(StopReason::kInternal);
    }
  };
  control.spare_frame = [&] { return writer->spare_frame(); };
  JobCheckpointer::Options checkpoints;
  checkpoints.job_id = id;
  checkpoints.job_dir = dir;
  checkpoints.interval_s = config_.checkpoint_interval_s;
  checkpoints.spec_json = spec_json;
  checkpoints.mesh_fingerprint = mesh_fingerprint(problem.mesh);
  checkpoints.min_free_bytes = config_.min_free_bytes;
  checkpoints.free_bytes = [this] { return free_bytes(); };
  JobCheckpointer checkpointer(std::move(checkpoints), *writer);
  checkpointer.attach(control, cancel);
  if (resume) control.resume = &resume->state;

  RunResult result;
  try {
    result = run_simulation(problem, options, control);
  } catch (const std::exception& e) {
    writer.reset();  // removes the temporary file
    remove_job_checkpoint(dir);
    finish(JobState::kFailed, reason::kInternal, std::string("solver: ") + e.what(), "", nullptr);
    return;
  }

  if (result.status == RunStatus::kCancelled && cancel.reason() == StopReason::kShutdown) {
    // Not the job's fault: queue it again so the next daemon start completes it, from the
    // checkpoint taken where it stopped (made durable first). The partial file is discarded
    // (writer destructor).
    try {
      writer->drain();
    } catch (const std::exception& e) {
      log_warning("job ", id, ": at shutdown: ", e.what());
    }
    writer.reset();
    requeue(reason::kShutdown);
    return;
  }

  // Decide the outcome, then make the file durable before recording it.
  JobState state = JobState::kSucceeded;
  std::string why, error;
  switch (result.status) {
    case RunStatus::kCompleted:
      break;
    case RunStatus::kFailed:
      state = JobState::kFailed;
      why = failure_reason(result.failure);
      error = result.error;
      break;
    case RunStatus::kCancelled:
      switch (cancel.reason()) {
        case StopReason::kWallTime:
          state = JobState::kFailed;
          why = reason::kWallTimeExceeded;
          error = "wall time limit of " + seconds(config_.max_wall_time_s) +
                  " reached at simulated time " + seconds(last_progress.simulated_time_s);
          break;
        case StopReason::kInternal:
          state = JobState::kFailed;
          why = disk_full ? reason::kDiskFull : reason::kInternal;
          error = "writing a field frame: " + io_error;
          break;
        default:
          state = JobState::kCancelled;
          why = reason::kCancelledByUser;
          error = "cancelled by user at simulated time " + seconds(last_progress.simulated_time_s);
          break;
      }
      break;
  }
  if (state == JobState::kSucceeded) last_progress.fraction = 1.0;

  std::optional<StoredSummary> stored;
  try {
    RunSummary summary = summarize(problem, result);
    summary.meshing_time_s = meshing.seconds;
    summary.mesh_cache = to_string(meshing.cache);
    stored = make_stored_summary(summary, result.history);
    if (state != JobState::kFailed || (why != reason::kInternal && why != reason::kDiskFull)) {
      writer->finish(result.history, summary, state == JobState::kSucceeded, error);
    }
  } catch (const std::exception& e) {
    // Without a durable file the run cannot count as a success.
    writer.reset();
    remove_job_checkpoint(dir);
    finish(JobState::kFailed, reason::kInternal, std::string("finishing results: ") + e.what(), "",
           nullptr);
    return;
  }
  const std::string path = fs::exists(writer->h5_path()) ? writer->h5_path() : std::string();
  writer.reset();              // no checkpoint is being written any more
  remove_job_checkpoint(dir);  // its frames are in the result now
  if (state == JobState::kSucceeded && !path.empty() && checkpointer.final_state()) {
    try {  // for ExtendJob; without it an extension runs from t = 0
      save_final_state(dir, spec_json, mesh_fingerprint(problem.mesh), *checkpointer.final_state(),
                       path);
    } catch (const std::exception& e) {
      log_warning("job ", id, ": final state not kept: ", e.what());
    }
  }
  finish(state, why, error, path, stored ? &*stored : nullptr);
  if (!catalogue_.get(id)) {
    // Deleted while it ran: do not leave an orphan folder behind.
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
}

}  // namespace softshock::server
