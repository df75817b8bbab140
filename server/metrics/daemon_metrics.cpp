#include "server/metrics/daemon_metrics.hpp"

#include <sys/statvfs.h>

#include <chrono>

namespace softshock::server {

using metrics::Sample;
using metrics::Type;

namespace {

// Seconds a job waits for a worker: from a blink to a day in a long queue.
const std::vector<double> kQueueWaitBounds = {0.1, 0.5, 1, 5, 15, 60, 300, 900, 3600, 14400, 86400};
// Seconds a run takes: a test mesh's fraction of a second to the 6 h wall-time limit.
const std::vector<double> kRunBounds = {0.25, 1, 2.5, 5, 10, 30, 60, 300, 900, 3600, 21600};
// Seconds an RPC or HTTP request takes: a catalogue read's milliseconds to a WatchJob stream.
const std::vector<double> kRequestBounds = {0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25,
                                            0.5,   1,      2.5,   5,    10,    30,   120};

double process_start_seconds() {
  static const double start =
      std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
  return start;
}

}  // namespace

bool statvfs_disk(const std::string& path, DiskSpace* space) {
  struct statvfs s {};
  if (::statvfs(path.c_str(), &s) != 0) return false;
  const double unit = static_cast<double>(s.f_frsize);
  space->total_bytes = unit * static_cast<double>(s.f_blocks);
  space->free_bytes = unit * static_cast<double>(s.f_bavail);
  space->used_bytes = unit * static_cast<double>(s.f_blocks - s.f_bfree);
  return true;
}

DaemonMetrics::DaemonMetrics(const Catalogue& catalogue, std::string data_dir,
                             double min_free_bytes, std::string version, DiskStat disk)
    : catalogue_(catalogue),
      data_dir_(std::move(data_dir)),
      min_free_bytes_(min_free_bytes),
      disk_(std::move(disk)),
      queue_wait_(registry_.histogram(
          "softshock_job_queue_wait_seconds",
          "Time from a job's submission to the start of its run, per run started by this daemon.",
          {}, kQueueWaitBounds)),
      run_time_(registry_.histogram(
          "softshock_job_run_seconds",
          "Wall time of runs started by this daemon that ended, from start to the terminal state, "
          "by that state.",
          {"state"}, kRunBounds)),
      runs_finished_(registry_.counter(
          "softshock_job_runs_finished_total",
          "Runs started by this daemon that stopped, by outcome (SUCCEEDED, FAILED, CANCELLED, or "
          "REQUEUED when a shutdown sent the job back to the queue) and reason (Job.reason; "
          "'none' when empty).",
          {"outcome", "reason"})),
      element_steps_(registry_.counter(
          "softshock_element_steps_total",
          "Element-steps computed by runs of this daemon (elements x time steps, counted as runs "
          "progress); rate() of it is the daemon's element-steps per second.")),
      rpcs_(registry_.counter("grpc_server_handled_total",
                              "RPCs completed, by service, method, type and status code.",
                              {"grpc_service", "grpc_method", "grpc_type", "grpc_code"})),
      rpc_seconds_(registry_.histogram(
          "grpc_server_handling_seconds",
          "RPC latency from the call's start to its status, by service, method, type and code.",
          {"grpc_service", "grpc_method", "grpc_type", "grpc_code"}, kRequestBounds)),
      uploads_(registry_.counter("softshock_mesh_uploads_total",
                                 "Mesh uploads (UploadMesh calls) by outcome: stored or rejected.",
                                 {"outcome"})),
      upload_bytes_(registry_.counter("softshock_mesh_upload_bytes_total",
                                      "Bytes of mesh files received, by the upload's outcome.",
                                      {"outcome"})),
      http_requests_(registry_.counter(
          "softshock_http_requests_total",
          "HTTP requests by listener (dashboard, metrics), route and status code.",
          {"listener", "route", "code"})),
      http_seconds_(registry_.histogram("softshock_http_request_duration_seconds",
                                        "HTTP request latency by listener and route.",
                                        {"listener", "route"}, kRequestBounds)) {
  (void)process_start_seconds();
  // Series without labels exist from the start, at 0, so rate() and increase() see the first
  // run (a series that appears with its first observation loses that observation to them).
  queue_wait_.with();
  element_steps_.with();
  registry_.sampled(
      Type::kGauge, "softshock_jobs", "Jobs in the catalogue, by state.", {"state"}, [this] {
        const auto counts = catalogue_.counts();
        std::vector<Sample> out;
        for (JobState s : {JobState::kQueued, JobState::kRunning, JobState::kSucceeded,
                           JobState::kFailed, JobState::kCancelled}) {
          const auto it = counts.find(s);
          out.push_back(
              {{to_string(s)}, it == counts.end() ? 0.0 : static_cast<double>(it->second)});
        }
        return out;
      });
  registry_.sampled(Type::kGauge, "softshock_data_disk_total_bytes",
                    "Size of the filesystem holding the data folder.", {}, [this] {
                      DiskSpace d;
                      return disk_(data_dir_, &d) ? std::vector<Sample>{{{}, d.total_bytes}}
                                                  : std::vector<Sample>{};
                    });
  registry_.sampled(Type::kGauge, "softshock_data_disk_free_bytes",
                    "Free space the daemon may use on the data folder's filesystem (no job starts "
                    "and nothing is accepted below softshock_data_disk_reserve_bytes).",
                    {}, [this] {
                      DiskSpace d;
                      return disk_(data_dir_, &d) ? std::vector<Sample>{{{}, d.free_bytes}}
                                                  : std::vector<Sample>{};
                    });
  registry_.sampled(Type::kGauge, "softshock_data_disk_used_bytes",
                    "Used space on the data folder's filesystem (by everything on it).", {},
                    [this] {
                      DiskSpace d;
                      return disk_(data_dir_, &d) ? std::vector<Sample>{{{}, d.used_bytes}}
                                                  : std::vector<Sample>{};
                    });
  registry_.sampled(Type::kGauge, "softshock_data_disk_reserve_bytes",
                    "The free space the data folder keeps (--min-free-bytes).", {}, [this] {
                      return std::vector<Sample>{{{}, min_free_bytes_}};
                    });
  registry_.sampled(Type::kGauge, "softshock_catalogue_room_held",
                    "1 while the catalogue holds its reserved room for deletions on a full disk.",
                    {}, [this] {
                      return std::vector<Sample>{{{}, catalogue_.room_held() ? 1.0 : 0.0}};
                    });
  registry_.sampled(Type::kGauge, "softshock_build_info",
                    "Always 1; the version of softshockd in a label.", {"version"}, [version] {
                      return std::vector<Sample>{{{version}, 1.0}};
                    });
  registry_.sampled(Type::kGauge, "process_start_time_seconds",
                    "Start time of the process since the Unix epoch, in seconds.", {}, [] {
                      return std::vector<Sample>{{{}, process_start_seconds()}};
                    });
}

void DaemonMetrics::on_job_event(JobEventKind kind, const std::string& id,
                                 const JobProgressRecord* progress) {
  if (kind == JobEventKind::kProgress && progress != nullptr) {
    bool tracked = false;
    int64_t add = 0;
    {
      std::lock_guard lock(mutex_);
      auto it = runs_.find(id);
      if (it != runs_.end()) {
        tracked = true;
        Run& run = it->second;
        if (progress->elements > 0) run.elements = progress->elements;
        if (run.elements > 0 && progress->steps > run.steps_counted) {
          add = (progress->steps - run.steps_counted) * run.elements;
          run.steps_counted = progress->steps;
        }
      }
    }
    if (add > 0) element_steps_.with().inc(static_cast<double>(add));
    if (!tracked) run_started(id);
  } else if (kind == JobEventKind::kStopped) {
    run_stopped(id);
  }
}

void DaemonMetrics::run_started(const std::string& id) {
  const auto job = catalogue_.get(id);
  if (!job || job->state != JobState::kRunning || job->start_us <= 0) return;
  {
    std::lock_guard lock(mutex_);
    if (!runs_.emplace(id, Run{}).second) return;  // another thread was first
  }
  queue_wait_.with().observe(static_cast<double>(job->start_us - job->create_us) / 1e6);
}

void DaemonMetrics::run_stopped(const std::string& id) {
  Run run;
  {
    std::lock_guard lock(mutex_);
    const auto it = runs_.find(id);
    if (it == runs_.end()) return;  // not started here, or already counted
    run = it->second;
  }
  const auto job = catalogue_.get(id);
  if (job && job->state == JobState::kRunning) return;  // not stopped yet: the runner tells again
  {
    std::lock_guard lock(mutex_);
    if (runs_.erase(id) == 0) return;  // another thread counted it meanwhile
  }
  if (!job) return;  // deleted while it ran
  const std::string outcome = job->state == JobState::kQueued ? "REQUEUED" : to_string(job->state);
  runs_finished_.with({outcome, job->reason.empty() ? "none" : job->reason}).inc();
  if (!is_terminal(job->state)) return;
  if (job->start_us > 0 && job->finish_us >= job->start_us) {
    run_time_.with({to_string(job->state)})
        .observe(static_cast<double>(job->finish_us - job->start_us) / 1e6);
  }
  // What the run's summary says it did, beyond what was counted live.
  if (const auto stored = catalogue_.summary(id)) {
    const double total =
        static_cast<double>(stored->summary.elements) * static_cast<double>(stored->summary.steps);
    const double counted =
        static_cast<double>(run.steps_counted) * static_cast<double>(run.elements);
    if (total > counted) element_steps_.with().inc(total - counted);
  }
}

std::size_t DaemonMetrics::tracked_runs() const {
  std::lock_guard lock(mutex_);
  return runs_.size();
}

void DaemonMetrics::rpc_handled(std::string_view service, std::string_view method,
                                std::string_view type, std::string_view code, double seconds) {
  const metrics::LabelValues labels{std::string(service), std::string(method), std::string(type),
                                    std::string(code)};
  rpcs_.with(labels).inc();
  rpc_seconds_.with(labels).observe(seconds);
}

void DaemonMetrics::mesh_upload(bool stored, std::uint64_t bytes) {
  const std::string outcome = stored ? "stored" : "rejected";
  uploads_.with({outcome}).inc();
  upload_bytes_.with({outcome}).inc(static_cast<double>(bytes));
}

void DaemonMetrics::http_request(std::string_view listener, std::string_view route, int status,
                                 double seconds) {
  http_requests_.with({std::string(listener), std::string(route), std::to_string(status)}).inc();
  http_seconds_.with({std::string(listener), std::string(route)}).observe(seconds);
}

}  // namespace softshock::server
