#include "server/jobs/slurm_executor.hpp"

#include <pwd.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include "server/jobs/process_io.hpp"
#include "server/log.hpp"
#include "solver/io/result_file.hpp"
#include "solver/mesh_file_path.hpp"

namespace softshock::server {

namespace fs = std::filesystem;

namespace {

constexpr std::size_t kMaxArrayTasks = 1000;  // Slurm's default MaxArraySize is 1001
constexpr const char* kNamePrefix = "softshock-";
// The Slurm id recorded for a job whose Slurm job was purged before we learnt its id: no Slurm
// command knows it, so its files decide its outcome.
constexpr const char* kPurgedPrefix = "purged-";

}  // namespace

SlurmExecutor::SlurmExecutor(SlurmConfig config, Catalogue& catalogue, JobRunner& runner,
                             JobEvents& events)
    : config_(std::move(config)), catalogue_(catalogue), runner_(runner), events_(events) {
  fs::create_directories(fs::path(config_.shared_dir) / "jobs");
  fs::create_directories(fs::path(config_.shared_dir) / "batches");
  if (const passwd* pw = ::getpwuid(::getuid())) user_ = pw->pw_name;
  // Re-attach: what was handed to Slurm before a stop or crash is watched again, never resent.
  for (const auto& s : catalogue_.submitted_jobs()) {
    Tracked t;
    t.slurm_id = s.slurm_job_id;
    t.running = s.state == JobState::kRunning;
    if (auto job = catalogue_.get(s.id)) t.attempt = job->attempt;
    jobs_.emplace(s.id, t);
  }
  if (!jobs_.empty()) log_info("slurm: re-attached to ", jobs_.size(), " job(s) on Slurm");
}

SlurmExecutor::~SlurmExecutor() {
  shutdown(std::chrono::milliseconds(0));
}

std::string SlurmExecutor::job_dir(const std::string& id) const {
  return (fs::path(config_.shared_dir) / "jobs" / id).string();
}

void SlurmExecutor::start() {
  std::lock_guard lock(mutex_);
  if (started_ || stopping_) return;
  started_ = true;
  thread_ = std::thread([this] { loop(); });
}

bool SlurmExecutor::reserve(std::size_t slots) {
  std::lock_guard lock(mutex_);
  if (stopping_) return false;
  std::size_t waiting = pending_.size();
  for (const auto& [id, t] : jobs_) waiting += t.running ? 0 : 1;
  if (waiting + reserved_ + slots > config_.max_queued) return false;
  reserved_ += slots;
  return true;
}

void SlurmExecutor::release(std::size_t slots) {
  std::lock_guard lock(mutex_);
  reserved_ -= std::min(reserved_, slots);
}

void SlurmExecutor::enqueue(const std::string& id, int priority, int64_t seq, bool reserved) {
  {
    std::lock_guard lock(mutex_);
    if (reserved && reserved_ > 0) --reserved_;
    // Already on Slurm (submitted with its grid, or re-attached): nothing more to do.
    if (jobs_.count(id)) return;
    for (const auto& p : pending_) {
      if (p.id == id) return;
    }
    pending_.push_back({id, priority, seq});
    nudged_ = true;
  }
  wake_.notify_one();
}

bool SlurmExecutor::cancel(const std::string& id, StopReason why) {
  {
    std::lock_guard lock(mutex_);
    const auto p = std::find_if(pending_.begin(), pending_.end(),
                                [&](const Pending& e) { return e.id == id; });
    if (p != pending_.end()) {
      pending_.erase(p);
      return true;
    }
    const auto t = jobs_.find(id);
    if (t == jobs_.end()) return false;
    if (t->second.cancel == StopReason::kNone) t->second.cancel = why;
    nudged_ = true;
  }
  wake_.notify_one();
  return true;
}

bool SlurmExecutor::is_running(const std::string& id) const {
  std::lock_guard lock(mutex_);
  const auto t = jobs_.find(id);
  return t != jobs_.end() && t->second.running;
}

std::size_t SlurmExecutor::queued() const {
  std::lock_guard lock(mutex_);
  std::size_t n = pending_.size();
  for (const auto& [id, t] : jobs_) n += t.running ? 0 : 1;
  return n;
}

std::size_t SlurmExecutor::running() const {
  std::lock_guard lock(mutex_);
  std::size_t n = 0;
  for (const auto& [id, t] : jobs_) n += t.running ? 1 : 0;
  return n;
}

std::vector<std::string> SlurmExecutor::shutdown(std::chrono::milliseconds) {
  {
    std::lock_guard lock(mutex_);
    if (stopping_ && !thread_.joinable()) return {};
    stopping_ = true;
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
  return {};
}

void SlurmExecutor::loop() {
  const auto interval = std::chrono::duration<double>(config_.poll_s);
  for (;;) {
    bool stop = false;
    {
      std::unique_lock lock(mutex_);
      wake_.wait_for(lock, interval, [this] { return stopping_ || nudged_; });
      nudged_ = false;
      stop = stopping_;
    }
    try {
      if (stop) {
        // Cancellations already answered to a client must reach Slurm before we go.
        send_cancels();
        return;
      }
      record_unmarked();
      if (!adopted_) adopt_submitted_before_crash();
      if (adopted_) submit_pending();
      send_cancels();
      poll();
    } catch (const std::exception& e) {
      log_error("slurm: ", e.what());
    }
  }
}

void SlurmExecutor::adopt_submitted_before_crash() {
  std::vector<std::string> waiting;
  {
    std::lock_guard lock(mutex_);
    for (const auto& p : pending_) waiting.push_back(p.id);
  }
  if (waiting.empty()) {
    adopted_ = true;
    return;
  }
  const CommandResult r = run_command(
      {"squeue", "-h", "--states=all", "-u", user_.empty() ? "root" : user_, "-o", "%F|%j"});
  if (r.status != 0) {
    // Submitting now could send a job a second time: wait for Slurm to answer.
    log_warning("slurm: squeue failed (", first_line(r.err), "); not submitting until it works");
    return;
  }
  const std::set<std::string> unsubmitted(waiting.begin(), waiting.end());
  std::vector<std::pair<std::string, std::string>> found;
  std::istringstream lines(r.out);
  std::set<std::string> seen;
  for (std::string line; std::getline(lines, line);) {
    const auto bar = line.find('|');
    if (bar == std::string::npos) continue;
    const std::string base = trim(line.substr(0, bar)), name = trim(line.substr(bar + 1));
    if (name.rfind(kNamePrefix, 0) != 0 || !seen.insert(base).second) continue;
    const fs::path ids_file = fs::path(config_.shared_dir) / "batches" / (name + ".ids");
    std::vector<std::string> ids;
    std::istringstream in(read_text(ids_file));
    for (std::string id; std::getline(in, id);) {
      if (!trim(id).empty()) ids.push_back(trim(id));
    }
    for (std::size_t k = 0; k < ids.size(); ++k) {
      if (!unsubmitted.count(ids[k])) continue;
      found.emplace_back(ids[k], ids.size() == 1 ? base : base + "_" + std::to_string(k));
    }
  }
  // Not listed at all, but its batch ran (solve.log is removed before every submission and
  // written only by the batch): Slurm took it and has since purged it. Resubmitting would run
  // it twice and delete the first run's result; it is adopted instead, and its files decide.
  std::set<std::string> adopted;
  for (const auto& [id, slurm_id] : found) adopted.insert(id);
  for (const auto& id : waiting) {
    std::error_code ec;
    if (adopted.count(id) || !fs::exists(fs::path(job_dir(id)) / "solve.log", ec)) continue;
    found.emplace_back(id, kPurgedPrefix + id);
  }
  if (!found.empty()) {
    catalogue_.mark_submitted(found);
    std::lock_guard lock(mutex_);
    for (const auto& [id, slurm_id] : found) {
      std::erase_if(pending_, [&](const Pending& p) { return p.id == id; });
      jobs_[id].slurm_id = slurm_id;
      if (auto job = catalogue_.get(id)) jobs_[id].attempt = job->attempt;
      log_warning("slurm: job ", id, " was submitted as ", slurm_id,
                  " just before the daemon stopped: re-attached, not resubmitted");
    }
  }
  adopted_ = true;
}

void SlurmExecutor::fail_unsubmitted(const JobRecord& job, const std::string& why,
                                     const std::string& error) {
  // start + finish, so the attempt history records the failure like any other run's.
  if (auto started = catalogue_.start(job.id, now_us())) {
    catalogue_.finish(job.id, started->attempt, JobState::kFailed, why, error, "", {}, nullptr,
                      now_us());
    log_info("job ", job.id, " FAILED ", why, ": ", error);
  }
  events_.forget(job.id);
}

void SlurmExecutor::submit_pending() {
  std::vector<Pending> batch;
  {
    std::lock_guard lock(mutex_);
    batch.swap(pending_);
  }
  if (batch.empty()) return;
  std::sort(batch.begin(), batch.end(), [](const Pending& a, const Pending& b) {
    return a.priority != b.priority ? a.priority > b.priority : a.seq < b.seq;
  });
  std::vector<JobRecord> singles;
  std::map<std::string, std::vector<JobRecord>> grids;
  std::set<std::string> taken;
  std::size_t next = 0;  // batch[next..] not looked at yet
  // A catalogue error while sorting the batch out puts back what was not sorted yet (and what
  // was sorted but not sent): those jobs wait for the next round instead of being dropped.
  auto put_back = [&] {
    std::set<std::string> back;
    for (std::size_t k = next; k < batch.size(); ++k) back.insert(batch[k].id);
    for (const auto& j : singles) back.insert(j.id);
    for (const auto& [g, points] : grids) {
      for (const auto& j : points) back.insert(j.id);
    }
    std::lock_guard lock(mutex_);
    for (const auto& p : batch) {
      if (back.count(p.id) && std::none_of(pending_.begin(), pending_.end(),
                                           [&](const Pending& q) { return q.id == p.id; })) {
        pending_.push_back(p);
      }
    }
  };
  try {
    collect_batches(batch, next, singles, grids, taken);
  } catch (...) {
    put_back();
    throw;
  }
  {
    // Points taken with their grid are no longer waiting for a later round.
    std::lock_guard lock(mutex_);
    std::erase_if(pending_, [&](const Pending& p) { return taken.count(p.id) != 0; });
  }
  for (const auto& [grid, points] : grids) {
    for (std::size_t first = 0; first < points.size(); first += kMaxArrayTasks) {
      const auto last = std::min(points.size(), first + kMaxArrayTasks);
      submit_batch_safely({points.begin() + static_cast<std::ptrdiff_t>(first),
                           points.begin() + static_cast<std::ptrdiff_t>(last)});
    }
  }
  for (const auto& job : singles) submit_batch_safely({job});
}

// One batch's failure is its own: its jobs are failed with the reason (they never reached
// Slurm), or, if even that cannot be recorded, wait for the next round; other batches go on.
void SlurmExecutor::submit_batch_safely(const std::vector<JobRecord>& jobs) {
  try {
    submit_batch(jobs);
    return;
  } catch (const std::exception& e) {
    log_error("slurm: submitting ", jobs.size(), " job(s) failed: ", e.what());
    for (const auto& job : jobs) {
      bool tracked = false;
      {
        std::lock_guard lock(mutex_);
        tracked = jobs_.count(job.id) != 0;
      }
      if (tracked) continue;  // it did reach Slurm
      try {
        fail_unsubmitted(job, reason::kInternal,
                         std::string("preparing the Slurm batch: ") + e.what());
      } catch (const std::exception& again) {
        log_error("slurm: job ", job.id, ": cannot record the failure (", again.what(),
                  "); retrying next round");
        std::lock_guard lock(mutex_);
        pending_.push_back({job.id, job.priority, job.seq});
      }
    }
  }
}

void SlurmExecutor::collect_batches(const std::vector<Pending>& batch, std::size_t& next,
                                    std::vector<JobRecord>& singles,
                                    std::map<std::string, std::vector<JobRecord>>& grids,
                                    std::set<std::string>& taken) {
  for (; next < batch.size(); ++next) {
    const Pending& p = batch[next];
    if (taken.count(p.id)) continue;
    auto job = catalogue_.get(p.id);
    if (!job || job->state != JobState::kQueued) continue;  // cancelled or deleted meanwhile
    if (job->reuse_result && runner_.reuse_identical(*job)) continue;
    if (job->grid_id.empty()) {
      singles.push_back(*job);
      taken.insert(job->id);
      continue;
    }
    if (grids.count(job->grid_id)) continue;
    // The whole grid at once, also points whose enqueue() has not arrived yet (the service
    // enqueues them one by one after the grid's single insert): one array job, not several.
    auto& points = grids[job->grid_id];
    for (const auto& gp : catalogue_.grid_points(job->grid_id)) {
      if (gp.state != JobState::kQueued) continue;
      {
        std::lock_guard lock(mutex_);
        if (jobs_.count(gp.job_id)) continue;
      }
      auto point = catalogue_.get(gp.job_id);
      if (!point || point->state != JobState::kQueued) continue;
      if (!catalogue_.slurm_job_id(point->id).empty()) continue;
      if (point->reuse_result && runner_.reuse_identical(*point)) continue;
      points.push_back(*point);
      taken.insert(point->id);
    }
  }
}

void SlurmExecutor::submit_batch(const std::vector<JobRecord>& jobs) {
  // Each job's folder: its spec as softshock-solve reads it, a copy of its mesh file if any.
  std::vector<JobRecord> ready;
  for (const auto& job : jobs) {
    try {
      const fs::path dir = job_dir(job.id);
      fs::create_directories(dir);
      for (const char* stale : {"result.h5", "result.xdmf", "result.h5.tmp", "solve.log"}) {
        fs::remove(dir / stale);
      }
      v1::RunSpec spec = parse_stored_spec(job.spec_json);
      if (spec.geometry().shape_case() == v1::Geometry::kMeshFile) {
        const fs::path source =
            resolve_mesh_file(runner_.meshes_dir(), spec.geometry().mesh_file());
        const fs::path copy = dir / source.filename();
        fs::copy_file(source, copy, fs::copy_options::overwrite_existing);
        spec.mutable_geometry()->set_mesh_file(copy.string());
      }
      write_text(dir / "spec.json", spec_to_json(spec));
      ready.push_back(job);
    } catch (const SpecError& e) {
      fail_unsubmitted(job, reason::kInvalidSpec, e.what());
    } catch (const std::exception& e) {
      fail_unsubmitted(job, reason::kInternal, std::string("preparing the job: ") + e.what());
    }
  }
  if (ready.empty()) return;

  const std::string name = kNamePrefix + ready.front().id;
  const fs::path batches = fs::path(config_.shared_dir) / "batches";
  std::string ids, quoted_ids;
  for (const auto& job : ready) {
    ids += job.id + "\n";
    quoted_ids += " " + sh_quote(job.id);
  }
  // Written before sbatch: after a crash in between, the name found in squeue leads here.
  write_text(batches / (name + ".ids"), ids);
  std::ostringstream script;
  script << "#!/bin/bash\n"
         << "# softshockd: " << ready.size() << " job(s); task k runs the k-th id.\n"
         << "ids=(" << quoted_ids << " )\n"
         << "id=${ids[${SLURM_ARRAY_TASK_ID:-0}]}\n"
         << "dir=" << sh_quote(fs::path(config_.shared_dir) / "jobs") << "/$id\n"
         << "exec " << sh_quote(config_.solver) << " --spec \"$dir/spec.json\" --out \"$dir\""
         << " --threads " << config_.solver_threads << " --max-elements " << config_.max_elements
         << " --max-end-time "
         << end_time_text(config_.max_end_time_s)
         // One mesh cache for every node: a grid meshes its geometry once cluster-wide.
         << " --mesh-cache " << sh_quote(fs::path(config_.shared_dir) / "cache" / "meshes");
  if (config_.checkpoint_interval_s > 0)  // continued when Slurm or the daemon runs it again
    script << " --checkpoint-dir \"$dir/checkpoint\" --checkpoint-interval "
           << end_time_text(config_.checkpoint_interval_s);
  script << " >\"$dir/summary.json\" 2>\"$dir/solve.log\"\n";
  const fs::path script_path = batches / (name + ".sh");
  write_text(script_path, script.str());

  std::vector<std::string> argv = {"sbatch", "--parsable", "--job-name=" + name,
                                   "--cpus-per-task=" + std::to_string(config_.solver_threads)};
  argv.push_back("--output=" +
                 (batches / (ready.size() > 1 ? "%x-%A_%a.out" : "%x-%j.out")).string());
  if (!config_.partition.empty()) argv.push_back("--partition=" + config_.partition);
  if (!config_.account.empty()) argv.push_back("--account=" + config_.account);
  if (!config_.time_limit.empty()) {
    argv.push_back("--time=" + config_.time_limit);
  } else if (config_.max_wall_time_s > 0) {
    argv.push_back("--time=" +
                   std::to_string(static_cast<long long>(std::ceil(config_.max_wall_time_s / 60))));
  }
  if (ready.size() > 1) {
    std::string array = "--array=0-" + std::to_string(ready.size() - 1);
    if (config_.array_throttle > 0) array += "%" + std::to_string(config_.array_throttle);
    argv.push_back(array);
  }
  argv.insert(argv.end(), config_.sbatch_args.begin(), config_.sbatch_args.end());
  argv.push_back(script_path.string());

  const CommandResult r = run_command(argv);
  const std::string base = parse_sbatch_job_id(r.out);
  if (r.status != 0 || base.empty()) {
    // sbatch refused (bad partition, account, limits): say why on each job, do not retry.
    const std::string error = "sbatch failed: " + trim(r.err.empty() ? r.out : r.err);
    for (const auto& job : ready) fail_unsubmitted(job, "SLURM_SUBMIT_FAILED", error);
    return;
  }
  std::vector<std::pair<std::string, std::string>> marks;
  for (std::size_t k = 0; k < ready.size(); ++k) {
    marks.emplace_back(ready[k].id, ready.size() == 1 ? base : base + "_" + std::to_string(k));
  }
  {
    // Tracked before the commit: a job on Slurm is watched (and finished) even if the commit
    // fails; the commit is then retried every round (and the .ids file covers a crash).
    std::lock_guard lock(mutex_);
    for (std::size_t k = 0; k < ready.size(); ++k) {
      Tracked& t = jobs_[ready[k].id];
      t.slurm_id = marks[k].second;
      t.attempt = ready[k].attempt;
    }
  }
  try {
    catalogue_.mark_submitted(marks);
  } catch (const std::exception& e) {
    log_error("slurm: recording Slurm job ", base, " failed (", e.what(), "); retrying");
    std::lock_guard lock(mutex_);
    unmarked_.insert(unmarked_.end(), marks.begin(), marks.end());
  }
  log_info("slurm: submitted ", ready.size(), " job(s) as ", base,
           ready.size() > 1 ? " (array)" : "", ", name ", name);
}

void SlurmExecutor::send_cancels() {
  std::vector<std::string> slurm_ids;
  {
    std::lock_guard lock(mutex_);
    for (auto& [id, t] : jobs_) {
      if (t.cancel != StopReason::kNone && !t.cancel_sent && !t.slurm_id.empty()) {
        slurm_ids.push_back(t.slurm_id);
        t.cancel_sent = true;
      }
    }
  }
  if (slurm_ids.empty()) return;
  std::vector<std::string> argv = {"scancel"};
  argv.insert(argv.end(), slurm_ids.begin(), slurm_ids.end());
  const CommandResult r = run_command(argv);
  if (r.status != 0) log_warning("slurm: scancel: ", first_line(r.err));
}

SlurmExecutor::Observed SlurmExecutor::look_up_gone(const std::string& id,
                                                    const std::string& slurm_id) {
  Observed o;
  if (slurm_id.rfind(kPurgedPrefix, 0) != 0) {  // a real Slurm id: ask Slurm first
    if (const auto r = run_command({"scontrol", "-o", "show", "job", slurm_id}); r.status == 0) {
      std::istringstream words(r.out);
      for (std::string w; words >> w;) {
        if (w.rfind("JobState=", 0) == 0) o.state = w.substr(9);
        if (w.rfind("Reason=", 0) == 0) o.detail = w.substr(7);
      }
      if (!o.state.empty()) return o;
    }
    // With accounting (slurmdbd), sacct knows jobs long gone from slurmctld's memory.
    if (const auto r = run_command({"sacct", "-n", "-P", "-X", "-j", slurm_id, "-o", "State"});
        r.status == 0 && !first_line(r.out).empty()) {
      o.state = first_line(r.out);
      return o;
    }
  }
  // Neither knows it (gone longer than MinJobAge and no accounting): the files tell.
  bool complete = false;
  try {
    ResultReader reader((fs::path(job_dir(id)) / "result.h5").string());
    complete = reader.info().complete;
  } catch (const std::exception&) {
  }
  o.state = complete ? "COMPLETED" : "FAILED";
  o.detail = "Slurm no longer knows job " + slurm_id;
  return o;
}

void SlurmExecutor::poll() {
  std::map<std::string, std::string> watched;  // our id -> Slurm id
  {
    std::lock_guard lock(mutex_);
    for (const auto& [id, t] : jobs_) watched.emplace(id, t.slurm_id);
  }
  if (watched.empty()) return;
  // One squeue for everything: -r lists each array task on its own line ("123_4").
  const CommandResult r = run_command({"squeue", "-h", "-r", "--states=all", "-u",
                                       user_.empty() ? "root" : user_, "-o", "%i|%T|%r"});
  if (r.status != 0) {
    log_warning("slurm: squeue failed: ", first_line(r.err), " (retrying)");
    return;
  }
  std::map<std::string, Observed> listed;
  std::istringstream lines(r.out);
  for (std::string line; std::getline(lines, line);) {
    const auto a = line.find('|'), b = line.find('|', a + 1);
    if (a == std::string::npos || b == std::string::npos) continue;
    listed[trim(line.substr(0, a))] = {trim(line.substr(a + 1, b - a - 1)),
                                       trim(line.substr(b + 1))};
  }
  for (const auto& [id, slurm_id] : watched) {
    // One job's error (a catalogue write, an unreadable result) must not hold up the others:
    // it is logged and that job is looked at again next round.
    try {
      const auto it = listed.find(slurm_id);
      on_state(id, it != listed.end() ? it->second : look_up_gone(id, slurm_id));
    } catch (const std::exception& e) {
      log_error("slurm: job ", id, " (", slurm_id, "): ", e.what(), " (retrying next round)");
    }
  }
}

void SlurmExecutor::record_unmarked() {
  std::vector<std::pair<std::string, std::string>> marks;
  {
    std::lock_guard lock(mutex_);
    marks.swap(unmarked_);
  }
  if (marks.empty()) return;
  try {
    catalogue_.mark_submitted(marks);
  } catch (...) {
    std::lock_guard lock(mutex_);
    unmarked_.insert(unmarked_.end(), marks.begin(), marks.end());
    throw;
  }
}

void SlurmExecutor::on_state(const std::string& id, const Observed& observed) {
  const SlurmOutcome outcome = map_slurm_state(observed.state);
  switch (outcome.kind) {
    case SlurmOutcome::Kind::kWaiting:
    case SlurmOutcome::Kind::kUnknown:
      return;
    case SlurmOutcome::Kind::kTerminal:
      finish(id, outcome, observed);
      return;
    case SlurmOutcome::Kind::kRunning:
      break;
  }
  bool running = false;
  {
    std::lock_guard lock(mutex_);
    running = jobs_[id].running;
  }
  if (!running) {
    auto job = catalogue_.start(id, now_us());
    if (!job) {
      // Cancelled or deleted here while Slurm started it: make sure Slurm stops it too.
      auto current = catalogue_.get(id);
      if (!current || is_terminal(current->state)) cancel(id, StopReason::kUser);
      return;
    }
    {
      std::lock_guard lock(mutex_);
      jobs_[id].running = true;
      jobs_[id].attempt = job->attempt;
    }
    events_.set_progress(id, {});
    log_info("job ", id, " started on Slurm (attempt ", job->attempt, ")");
  }
  if (auto p = progress_from_log(read_text(fs::path(job_dir(id)) / "solve.log"))) {
    events_.set_progress(id, *p);
  }
}

void SlurmExecutor::finish(const std::string& id, const SlurmOutcome& outcome,
                           const Observed& observed) {
  Tracked tracked;
  {
    std::lock_guard lock(mutex_);
    tracked = jobs_[id];
  }
  const fs::path shared = job_dir(id);
  auto forget = [&] {
    std::lock_guard lock(mutex_);
    jobs_.erase(id);
  };
  auto record = catalogue_.get(id);
  if (record && record->state == JobState::kQueued) {
    // Finished between two polls without being seen running.
    if (auto started = catalogue_.start(id, now_us())) record = started;
  }
  if (!record || record->state != JobState::kRunning) {
    // Cancelled or deleted here already; nothing to record.
    forget();
    std::error_code ec;
    fs::remove_all(shared, ec);
    if (!record) fs::remove_all(runner_.job_dir(id), ec);
    events_.forget(id);
    return;
  }

  JobState state = outcome.state;
  std::string why = outcome.reason, error;
  std::optional<StoredSummary> stored;
  std::string result_path;
  JobProgressRecord progress = events_.progress(id).value_or(JobProgressRecord{});
  const std::string h5 = (shared / "result.h5").string();
  // The result, complete or partial, goes into the job's own folder like a local run's.
  if (fs::exists(h5)) {
    try {
      bool complete = false;
      stored = stored_summary_from_result(h5, &complete);
      result_path = link_result_files(h5, runner_.job_dir(id));
      if (state == JobState::kSucceeded && !complete) {
        state = JobState::kFailed;
        why = reason::kInternal;
        error = "Slurm reports COMPLETED but result.h5 is not marked complete";
      }
      progress.steps = stored->summary.steps;
      progress.simulated_time_s = stored->summary.end_time_s;
    } catch (const std::exception& e) {
      stored.reset();
      result_path.clear();
      if (state == JobState::kSucceeded) {
        state = JobState::kFailed;
        why = reason::kInternal;
        error = std::string("ingesting the result: ") + e.what();
      }
    }
  } else if (state == JobState::kSucceeded) {
    state = JobState::kFailed;
    why = reason::kInternal;
    error = "Slurm reports COMPLETED but there is no result.h5";
  }
  const std::string log_text = read_text(shared / "solve.log");
  if (state == JobState::kCancelled) {
    why = tracked.cancel == StopReason::kUser ? reason::kCancelledByUser : "SLURM_CANCELLED";
    error = "Slurm job " + tracked.slurm_id + " cancelled";
  } else if (state == JobState::kFailed && error.empty()) {
    // A solver that stopped for a physical cause says which in its result's summary: the job
    // fails with the reason a local run gives (MESH_DISTORTION, ...), Slurm's word stays in error.
    if (stored && stored->summary.status == "failed") {
      if (std::string solver = failure_reason(stored->summary.failure); !solver.empty())
        why = solver;
    }
    error = "Slurm job " + tracked.slurm_id + " " + observed.state;
    if (!observed.detail.empty() && observed.detail != "None")
      error += " (" + observed.detail + ")";
    if (const std::string solver = last_line(log_text); !solver.empty()) error += ": " + solver;
  }
  if (state == JobState::kSucceeded) progress.fraction = 1.0;
  if (!log_text.empty()) {
    std::error_code ec;
    fs::create_directories(runner_.job_dir(id), ec);
    std::ofstream(fs::path(runner_.job_dir(id)) / "solve.log") << log_text;
  }

  bool ok = false;
  try {
    ok = catalogue_.finish(id, record->attempt, state, why, error, result_path, progress,
                           stored ? &*stored : nullptr, now_us());
  } catch (const std::exception& e) {
    // The outcome could not be recorded with its summary: a plain FAILED may still commit
    // (if not, this throws and the poll loop tries again next round).
    state = JobState::kFailed;
    why = reason::kInternal;
    error = "recording the outcome of Slurm job " + tracked.slurm_id + ": " + e.what();
    log_error("job ", id, ": ", error);
    ok = catalogue_.finish(id, record->attempt, state, why, error, "", progress, nullptr, now_us());
  }
  if (ok) {
    log_info("job ", id, " ", to_string(state), " on Slurm (", tracked.slurm_id, ")",
             why.empty() ? "" : " " + why, error.empty() ? "" : ": " + error);
  }
  forget();
  events_.forget(id);
  std::error_code ec;
  fs::remove_all(shared, ec);
  if (!catalogue_.get(id)) fs::remove_all(runner_.job_dir(id), ec);  // deleted meanwhile
}

}  // namespace softshock::server
