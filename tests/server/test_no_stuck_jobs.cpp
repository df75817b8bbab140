// No job is ever left RUNNING: non-finite summary figures commit, an error while recording a
// job's outcome turns it FAILED with the reason, and under the slurm executor one bad job or
// one failing batch holds up no other. Faults are injected with SQLite triggers (a write that
// fails like a full disk would) and with stand-in Slurm commands on PATH.
#include <gtest/gtest.h>
#include <sqlite3.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <thread>

#include "server/jobs/grid.hpp"
#include "server/jobs/job_events.hpp"
#include "server/jobs/job_runner.hpp"
#include "server/jobs/slurm_executor.hpp"
#include "server/store/catalogue.hpp"

namespace softshock::server {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

class NoStuckJobs : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ =
        fs::temp_directory_path() / ("softshock-stuck-" + std::to_string(std::random_device{}()));
    fs::create_directories(dir_ / "data" / "jobs");
    catalogue_ = std::make_unique<Catalogue>((dir_ / "data" / "catalogue.sqlite").string());
    RunnerConfig rc;
    rc.data_dir = (dir_ / "data").string();
    runner_ = std::make_unique<JobRunner>(rc, *catalogue_, events_);
  }
  void TearDown() override {
    if (!saved_path_.empty()) ::setenv("PATH", saved_path_.c_str(), 1);
    runner_.reset();
    catalogue_.reset();
    fs::remove_all(dir_);
  }

  // A tiny run (200 elements, 5 ns), stored as the service stores it.
  void insert(const std::string& id) {
    v1::RunSpec spec;
    spec.mutable_geometry()->set_target_elements(200);
    spec.mutable_run()->set_end_time(5e-9);
    spec.mutable_run()->set_output_interval(2.5e-9);
    const CanonicalSpec canonical = canonical_spec(spec, SpecLimits{});
    NewJob job;
    job.id = id;
    job.spec_json = canonical.json;
    job.spec_hash = canonical.hash;
    job.create_us = now_us();
    ASSERT_TRUE(catalogue_->insert(job).created);
  }

  // Runs SQL on the catalogue through a connection of its own (how the faults get in).
  void sql(const std::string& statement) {
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open((dir_ / "data" / "catalogue.sqlite").c_str(), &db), SQLITE_OK);
    sqlite3_busy_timeout(db, 5000);
    char* error = nullptr;
    const int rc = sqlite3_exec(db, statement.c_str(), nullptr, nullptr, &error);
    EXPECT_EQ(rc, SQLITE_OK) << (error ? error : "");
    sqlite3_free(error);
    sqlite3_close(db);
  }

  // Stand-ins for sbatch, squeue and scontrol: every submission is accepted, nothing is listed
  // by squeue, and scontrol reports each job FAILED (so each ends without a result file).
  void fake_slurm() {
    const fs::path bin = dir_ / "bin";
    fs::create_directories(bin);
    auto script = [&](const char* name, const std::string& body) {
      const fs::path p = bin / name;
      std::ofstream(p) << "#!/bin/sh\n" << body;
      fs::permissions(p, fs::perms::owner_all);
    };
    const std::string counter = (dir_ / "sbatch-count").string();
    const std::string args = (dir_ / "sbatch-args").string();
    script("sbatch", "echo \"$@\" >> '" + args + "'\nn=$(cat '" + counter +
                         "' 2>/dev/null || echo 1000)\nn=$((n+1))\necho $n > '" + counter +
                         "'\necho $n\n");
    script("squeue", "exit 0\n");
    script("scontrol", "echo \"JobId=$4 JobState=FAILED Reason=NonZeroExitCode\"\n");
    script("sacct", "exit 1\n");
    script("scancel", "exit 0\n");
    saved_path_ = std::getenv("PATH") ? std::getenv("PATH") : "/usr/bin:/bin";
    ::setenv("PATH", (bin.string() + ":" + saved_path_).c_str(), 1);
  }

  std::unique_ptr<SlurmExecutor> slurm_executor(SlurmConfig config = {}) {
    config.shared_dir = (dir_ / "slurm").string();
    config.poll_s = 0.05;
    return std::make_unique<SlurmExecutor>(config, *catalogue_, *runner_, events_);
  }

  // Waits (bounded) until the job is terminal; returns its record.
  JobRecord wait_terminal(const std::string& id, std::chrono::seconds limit = 20s) {
    const auto deadline = std::chrono::steady_clock::now() + limit;
    for (;;) {
      auto job = catalogue_->get(id);
      if (!job) ADD_FAILURE() << id << " vanished";
      if (!job || is_terminal(job->state) || std::chrono::steady_clock::now() > deadline) {
        return job.value_or(JobRecord{});
      }
      std::this_thread::sleep_for(20ms);
    }
  }

  fs::path dir_;
  JobEvents events_;
  std::unique_ptr<Catalogue> catalogue_;
  std::unique_ptr<JobRunner> runner_;
  std::string saved_path_;
};

TEST_F(NoStuckJobs, NonFiniteSummaryFiguresCommitAndReadBackAsNaN) {
  insert("nan");
  auto started = catalogue_->start("nan", now_us());
  ASSERT_TRUE(started);
  StoredSummary stored;
  stored.summary.status = "failed";
  stored.summary.max_abar = NAN;
  stored.summary.max_abar_first_cycle = NAN;
  stored.summary.energy_injected_J_per_m = INFINITY;
  stored.summary.groups.tbar_pulse = NAN;
  stored.summary.min_dt_s = NAN;
  JobProgressRecord progress;
  progress.simulated_time_s = NAN;
  progress.dt_s = NAN;
  ASSERT_TRUE(catalogue_->finish("nan", started->attempt, JobState::kFailed, reason::kNonFinite,
                                 "x", "", progress, &stored, now_us()));
  const auto job = catalogue_->get("nan");
  EXPECT_EQ(job->state, JobState::kFailed);
  EXPECT_EQ(job->progress.simulated_time_s, 0.0) << "non-finite progress is stored as 0";
  const auto back = catalogue_->summary("nan");
  ASSERT_TRUE(back);
  EXPECT_TRUE(std::isnan(back->summary.max_abar));
  EXPECT_TRUE(std::isnan(back->summary.groups.tbar_pulse));
  EXPECT_TRUE(std::isnan(back->summary.min_dt_s));
  EXPECT_EQ(back->summary.energy_injected_J_per_m, INFINITY);
  // A filter on a NaN figure never matches (it is "not known"), in either direction.
  for (bool above : {true, false}) {
    JobQuery q;
    RangeCondition c{"max_abar"};
    (above ? c.gt : c.lt) = 0.0;
    q.conditions = {c};
    EXPECT_TRUE(catalogue_->query(q).empty()) << (above ? "gt" : "lt");
  }
}

TEST_F(NoStuckJobs, AnOutcomeThatCannotBeRecordedFailsTheJobWithTheReason) {
  insert("j1");
  sql("CREATE TRIGGER full_disk BEFORE INSERT ON job_summaries "
      "BEGIN SELECT RAISE(ABORT, 'simulated: database or disk is full'); END");
  CancelToken token;
  EXPECT_NO_THROW(runner_->run("j1", token));
  const auto job = catalogue_->get("j1");
  EXPECT_EQ(job->state, JobState::kFailed);
  EXPECT_EQ(job->reason, reason::kInternal);
  EXPECT_NE(job->error.find("simulated: database or disk is full"), std::string::npos)
      << job->error;
  EXPECT_NE(job->error.find("SUCCEEDED"), std::string::npos) << "names what it was recording";
}

TEST_F(NoStuckJobs, SlurmPollIsolatesAJobWhoseOutcomeCannotBeRecorded) {
  fake_slurm();
  insert("aaaa");  // polled first (map order)
  insert("bbbb");
  sql("CREATE TRIGGER stuck BEFORE UPDATE OF state ON jobs WHEN NEW.id = 'aaaa' AND "
      "NEW.state IN (3, 4, 5) BEGIN SELECT RAISE(ABORT, 'simulated: disk full'); END");
  auto slurm = slurm_executor();
  for (const auto& q : catalogue_->queued_jobs()) slurm->enqueue(q.id, q.priority, q.seq, false);
  slurm->start();
  const JobRecord b = wait_terminal("bbbb");
  EXPECT_EQ(b.state, JobState::kFailed);
  EXPECT_EQ(b.reason, "SLURM_FAILED");
  EXPECT_EQ(catalogue_->get("aaaa")->state, JobState::kRunning) << "its writes all fail";
  // Once the catalogue takes writes again, the next round records it.
  sql("DROP TRIGGER stuck");
  const JobRecord a = wait_terminal("aaaa");
  EXPECT_EQ(a.state, JobState::kFailed);
  EXPECT_EQ(a.reason, "SLURM_FAILED");
  slurm->shutdown(0ms);
}

// Not about stuck jobs, but the same stand-in Slurm: the daemon's limits reach the cluster.
TEST_F(NoStuckJobs, SlurmJobsGetTheDaemonsLimits) {
  fake_slurm();
  insert("eeee");
  SlurmConfig config;
  config.max_wall_time_s = 21600;
  config.max_elements = 5000;
  config.max_end_time_s = 2e-6;
  auto slurm = slurm_executor(config);
  for (const auto& q : catalogue_->queued_jobs()) slurm->enqueue(q.id, q.priority, q.seq, false);
  slurm->start();
  wait_terminal("eeee");
  slurm->shutdown(0ms);
  std::ifstream args(dir_ / "sbatch-args");
  const std::string sbatch((std::istreambuf_iterator<char>(args)), {});
  EXPECT_NE(sbatch.find("--time=360 "), std::string::npos) << sbatch;
  std::ifstream script(dir_ / "slurm" / "batches" / "softshock-eeee.sh");
  const std::string batch((std::istreambuf_iterator<char>(script)), {});
  EXPECT_NE(batch.find("--max-elements 5000 --max-end-time 2e-06"), std::string::npos) << batch;
}

// The daemon died between sbatch and recording the Slurm id, and Slurm has purged the job
// since: its batch ran (solve.log), so it is not sent a second time; its files decide.
TEST_F(NoStuckJobs, SlurmJobPurgedBeforeItsIdWasRecordedIsNotResubmitted) {
  fake_slurm();
  insert("ffff");
  fs::create_directories(dir_ / "slurm" / "jobs" / "ffff");
  std::ofstream(dir_ / "slurm" / "jobs" / "ffff" / "solve.log")
      << "softshock-solve: run failed: element inversion\n";
  auto slurm = slurm_executor();
  for (const auto& q : catalogue_->queued_jobs()) slurm->enqueue(q.id, q.priority, q.seq, false);
  slurm->start();
  const JobRecord f = wait_terminal("ffff");
  slurm->shutdown(0ms);
  EXPECT_EQ(f.state, JobState::kFailed);
  EXPECT_NE(f.error.find("element inversion"), std::string::npos) << f.error;
  EXPECT_FALSE(fs::exists(dir_ / "sbatch-args")) << "sbatch was called: a second run";
}

TEST_F(NoStuckJobs, SlurmBatchThatCannotBePreparedFailsAloneAndOthersGoOut) {
  fake_slurm();
  insert("cccc");  // submitted first (lower seq)
  insert("dddd");
  // Its id list cannot be written: a folder stands where the file goes.
  fs::create_directories(dir_ / "slurm" / "batches" / "softshock-cccc.ids");
  auto slurm = slurm_executor();
  for (const auto& q : catalogue_->queued_jobs()) slurm->enqueue(q.id, q.priority, q.seq, false);
  slurm->start();
  const JobRecord c = wait_terminal("cccc");
  EXPECT_EQ(c.state, JobState::kFailed);
  EXPECT_EQ(c.reason, reason::kInternal);
  EXPECT_NE(c.error.find("preparing the Slurm batch"), std::string::npos) << c.error;
  const JobRecord d = wait_terminal("dddd");
  EXPECT_EQ(d.state, JobState::kFailed);
  EXPECT_EQ(d.reason, "SLURM_FAILED") << "it went to (the stand-in) Slurm";
  slurm->shutdown(0ms);
}

}  // namespace
}  // namespace softshock::server
