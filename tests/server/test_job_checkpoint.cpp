// A daemon job continued from its checkpoint (server/jobs/job_checkpoint.hpp): a job stopped by
// a shutdown after checkpoints every step is requeued, and its next run continues from the
// checkpoint taken where it stopped -- past the leftovers a crash would leave -- to a result
// bitwise equal to an uninterrupted job's (every frame, series and mode table); the checkpoint
// folder goes when the job ends. A damaged checkpoint is not used: the job runs from t = 0 to the
// same result. The runner's free-space hook (RunnerConfig::free_bytes, asked before the run, at
// each frame and at each checkpoint) counts the frames a run writes and stops the first run at
// a chosen step.
#include <gtest/gtest.h>

#include <atomic>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>

#include "server/jobs/grid.hpp"
#include "server/jobs/job_checkpoint.hpp"
#include "server/jobs/job_events.hpp"
#include "server/jobs/job_runner.hpp"
#include "server/store/catalogue.hpp"
#include "solver/io/result_file.hpp"

namespace softshock::server {
namespace {

namespace fs = std::filesystem;

bool same_bits(const std::vector<double>& a, const std::vector<double>& b) {
  return a.size() == b.size() &&
         (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0);
}

// Every frame's fields, every series and the mode table of two result files, bit for bit.
void expect_same_results(const std::string& a_path, const std::string& b_path) {
  const ResultReader a(a_path), b(b_path);
  EXPECT_TRUE(b.info().complete);
  ASSERT_EQ(a.info().frame_times.size(), b.info().frame_times.size());
  EXPECT_TRUE(same_bits(a.info().frame_times, b.info().frame_times));
  for (std::size_t f = 0; f < a.info().frame_times.size(); ++f)
    for (const char* name : {"displacement", "velocity", "J", "mean_stress", "von_mises"})
      EXPECT_TRUE(same_bits(a.field(f, name), b.field(f, name))) << "frame " << f << " " << name;
  ASSERT_FALSE(a.series_names().empty());
  for (const auto& name : a.series_names())
    EXPECT_TRUE(same_bits(a.series(name), b.series(name))) << name;
  std::size_t ra = 0, ca = 0, rb = 0, cb = 0;
  EXPECT_TRUE(same_bits(a.mode_amplitudes(ra, ca), b.mode_amplitudes(rb, cb)));
}

class JobCheckpoint : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("softshock-job-checkpoint-" + std::to_string(std::random_device{}()));
    fs::create_directories(dir_ / "data" / "jobs");
    catalogue_ = std::make_unique<Catalogue>((dir_ / "data" / "catalogue.sqlite").string());
  }
  void TearDown() override {
    catalogue_.reset();
    fs::remove_all(dir_);
  }

  // 400 triangles to 20 ns: 39 steps, 9 frames.
  void insert(const std::string& id) {
    v1::RunSpec spec;
    spec.mutable_geometry()->set_target_elements(400);
    spec.mutable_run()->set_end_time(2e-8);
    spec.mutable_run()->set_output_interval(2.5e-9);
    spec.mutable_run()->set_history_interval(1e-9);
    const CanonicalSpec canonical = canonical_spec(spec, SpecLimits{});
    NewJob job;
    job.id = id;
    job.spec_json = canonical.json;
    job.spec_hash = canonical.hash;
    job.create_us = now_us();
    ASSERT_TRUE(catalogue_->insert(job).created);
  }

  // Runs job `id` once with a runner of its own. `stop_at_call` > 0: the free-space hook's
  // call of that number asks for a shutdown. Returns the hook's calls.
  int run(const std::string& id, double checkpoint_interval_s, int stop_at_call = 0) {
    CancelToken cancel;
    std::atomic<int> calls{0};
    RunnerConfig rc;
    rc.data_dir = (dir_ / "data").string();
    rc.mesh_cache_bytes = 0;
    rc.checkpoint_interval_s = checkpoint_interval_s;
    rc.free_bytes = [&](const std::string&) {
      if (++calls == stop_at_call) cancel.request(StopReason::kShutdown);
      return 1e15;
    };
    JobRunner runner(rc, *catalogue_, events_);
    runner.run(id, cancel);
    return calls.load();
  }

  fs::path job_dir(const std::string& id) const { return dir_ / "data" / "jobs" / id; }
  std::string result(const std::string& id) const {
    const auto job = catalogue_->get(id);
    return job ? (dir_ / "data" / job->result_path).string() : "";
  }

  fs::path dir_;
  JobEvents events_;
  std::unique_ptr<Catalogue> catalogue_;
};

TEST_F(JobCheckpoint, AJobStoppedMidRunContinuesFromItsCheckpointToTheSameResult) {
  insert("reference");
  const int reference_calls = run("reference", 0);
  ASSERT_EQ(catalogue_->get("reference")->state, JobState::kSucceeded);
  EXPECT_EQ(reference_calls, 1 + 9);  // the start's check, then one per frame

  insert("stopped");
  // Checkpoints after every step; a shutdown asked for at the hook's 25th call (step 20 or so).
  run("stopped", 1e-12, 25);
  ASSERT_EQ(catalogue_->get("stopped")->state, JobState::kQueued);
  const fs::path checkpoint = job_dir("stopped") / "checkpoint";
  const Checkpoint taken = read_checkpoint((checkpoint / "state.ckpt").string());
  EXPECT_TRUE(taken.state.stopped);  // the one taken where the shutdown stopped it
  EXPECT_GT(taken.state.time_s, 5e-9);
  EXPECT_LT(taken.state.time_s, 1.5e-8);
  ASSERT_GE(taken.header.segments.size(), 2u);
  for (const auto& s : taken.header.segments) EXPECT_TRUE(fs::exists(checkpoint / s.file));

  // What a crash after the checkpoint leaves: a partial result, a half-written checkpoint and
  // frames sealed for a checkpoint that was never written.
  std::ofstream(job_dir("stopped") / "result.h5.tmp") << "partial";
  std::ofstream(checkpoint / "state.ckpt.tmp") << "half";
  std::ofstream(checkpoint / "frames_999999999999.h5") << "orphan";

  const int continued_calls = run("stopped", 0);
  const auto done = catalogue_->get("stopped");
  ASSERT_EQ(done->state, JobState::kSucceeded) << done->error;
  // Only the frames after the checkpoint were computed.
  EXPECT_EQ(continued_calls, 1 + 9 - static_cast<int>(taken.state.frames_written));
  EXPECT_LT(continued_calls, reference_calls);
  expect_same_results(result("reference"), result("stopped"));
  EXPECT_FALSE(fs::exists(checkpoint));
  for (const auto& entry : fs::recursive_directory_iterator(job_dir("stopped")))
    EXPECT_EQ(entry.path().string().find(".tmp"), std::string::npos) << entry.path();
}

TEST_F(JobCheckpoint, ADamagedCheckpointIsNotUsedAndTheJobRunsFromTheStart) {
  insert("reference");
  run("reference", 0);
  insert("damaged");
  run("damaged", 1e-12, 25);
  ASSERT_EQ(catalogue_->get("damaged")->state, JobState::kQueued);
  const fs::path state = job_dir("damaged") / "checkpoint" / "state.ckpt";
  {
    std::fstream f(state, std::ios::in | std::ios::out | std::ios::binary);
    const auto middle = static_cast<std::streamoff>(fs::file_size(state) / 2);
    f.seekg(middle);
    const char byte = static_cast<char>(f.get() ^ 0x10);  // one bit of the state arrays
    f.seekp(middle);
    f.put(byte);
  }
  EXPECT_THROW(read_checkpoint(state.string()), CheckpointError);
  const int calls = run("damaged", 0);
  ASSERT_EQ(catalogue_->get("damaged")->state, JobState::kSucceeded);
  EXPECT_EQ(calls, 1 + 9);  // every frame again
  expect_same_results(result("reference"), result("damaged"));
  EXPECT_FALSE(fs::exists(job_dir("damaged") / "checkpoint"));
}

}  // namespace
}  // namespace softshock::server
