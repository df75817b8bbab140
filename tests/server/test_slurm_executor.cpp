// The slurm executor's pure parts: Slurm state mapping, sbatch output, and the summary JSON
// read back from a cluster run (the integration test runs the rest against a real Slurm).
#include <gtest/gtest.h>

#include <cmath>

#include "server/jobs/job_runner.hpp"
#include "server/jobs/slurm_executor.hpp"

using namespace softshock;
using namespace softshock::server;

TEST(SlurmStates, MapOntoOurs) {
  using K = SlurmOutcome::Kind;
  EXPECT_EQ(map_slurm_state("PENDING").kind, K::kWaiting);
  EXPECT_EQ(map_slurm_state("REQUEUED").kind, K::kWaiting);
  EXPECT_EQ(map_slurm_state("RUNNING").kind, K::kRunning);
  EXPECT_EQ(map_slurm_state("COMPLETING").kind, K::kRunning);
  const auto done = map_slurm_state("COMPLETED");
  EXPECT_EQ(done.kind, K::kTerminal);
  EXPECT_EQ(done.state, JobState::kSucceeded);
  const auto cancelled = map_slurm_state("CANCELLED by 0");  // sacct's form
  EXPECT_EQ(cancelled.state, JobState::kCancelled);
  const auto timeout = map_slurm_state("TIMEOUT");  // sbatch --time is the daemon's wall limit
  EXPECT_EQ(timeout.state, JobState::kFailed);
  EXPECT_EQ(timeout.reason, "WALL_TIME_EXCEEDED");
  for (const char* s : {"FAILED", "OUT_OF_MEMORY", "NODE_FAIL"}) {
    const auto o = map_slurm_state(s);
    EXPECT_EQ(o.kind, K::kTerminal) << s;
    EXPECT_EQ(o.state, JobState::kFailed) << s;
    EXPECT_EQ(o.reason, std::string("SLURM_") + s);
  }
  EXPECT_EQ(map_slurm_state("SOMETHING_NEW").kind, K::kUnknown);
}

TEST(SlurmStates, SbatchParsableOutput) {
  EXPECT_EQ(parse_sbatch_job_id("123\n"), "123");
  EXPECT_EQ(parse_sbatch_job_id("456;cluster\n"), "456");
  EXPECT_EQ(parse_sbatch_job_id("sbatch: error: Batch job submission failed\n"), "");
  EXPECT_EQ(parse_sbatch_job_id(""), "");
}

TEST(SlurmStates, SummaryJsonRoundTrip) {
  RunSummary s;
  s.status = "failed";
  s.error = "element \"inversion\"";
  s.failure = failure_name(FailureKind::kElementInversion);
  s.elements = 412;
  s.nodes = 230;
  s.steps = 987;
  s.end_time_s = 2e-8;
  s.groups.pbar = 0.5;
  s.groups.tbar_pulse = NAN;  // written as null
  s.max_abar = 0.0123456789;
  s.dominant_mode_end = 6;
  s.rim_reflections_s = {1e-9, 3e-9};
  s.wall_time_s = 2.0, s.kernel_time_s = 1.25, s.diagnostics_time_s = 0.25;
  s.output_time_s = 0.125;
  const RunSummary r = parse_summary_json(summary_to_json(s));
  EXPECT_EQ(r.status, s.status);
  EXPECT_EQ(r.error, s.error);
  EXPECT_EQ(r.failure, "ELEMENT_INVERSION");
  EXPECT_EQ(failure_reason(r.failure), "ELEMENT_INVERSION");  // the job's reason, as a local run's
  EXPECT_EQ(r.elements, s.elements);
  EXPECT_EQ(r.steps, s.steps);
  EXPECT_DOUBLE_EQ(r.groups.pbar, 0.5);
  EXPECT_TRUE(std::isnan(r.groups.tbar_pulse));
  EXPECT_NEAR(r.max_abar, s.max_abar, 1e-12);
  EXPECT_EQ(r.dominant_mode_end, 6);
  EXPECT_EQ(r.rim_reflections_s.size(), 2u);
  EXPECT_EQ(r.solver_revision, kSolverRevision);
  // Where the time went survives the trip (a Slurm job's summary is read back this way).
  EXPECT_DOUBLE_EQ(r.kernel_time_s, 1.25);
  EXPECT_DOUBLE_EQ(r.diagnostics_time_s, 0.25);
  EXPECT_DOUBLE_EQ(r.output_time_s, 0.125);
  EXPECT_DOUBLE_EQ(r.output_share(), 0.0625);
  // A summary written before revisions were recorded: 0, which no running solver has.
  EXPECT_EQ(parse_summary_json(R"({"elements": 412, "steps": 987})").solver_revision, 0);
  EXPECT_FALSE(r.damage) << "no damage figures without damage";
  // The damage figures, printed only for a run with damage, come back too.
  s.damage = true;
  s.damage_onset_s = 1.1e-8, s.max_damaged_volume = 2.5e-11, s.max_damaged_radius_m = 2.8e-6;
  s.damage_dissipation_J_per_m = 0.0125, s.crack_energy_J_per_m = 0.5, s.damage_solves = 7;
  const RunSummary d = parse_summary_json(summary_to_json(s));
  EXPECT_TRUE(d.damage);
  EXPECT_DOUBLE_EQ(d.damage_onset_s, 1.1e-8);
  EXPECT_DOUBLE_EQ(d.max_damaged_volume, 2.5e-11);
  EXPECT_DOUBLE_EQ(d.max_damaged_radius_m, 2.8e-6);
  EXPECT_DOUBLE_EQ(d.damage_dissipation_J_per_m, 0.0125);
  EXPECT_DOUBLE_EQ(d.crack_energy_J_per_m, 0.5);
  EXPECT_EQ(d.damage_solves, 7);
}
