// What Slurm says and what the slurm executor says to it (docs/cluster.md): Slurm's job states in
// our model, sbatch's output, the solver's log lines read back, and the shell text of a batch
// script. Pure functions, tested without a cluster (tests/server/test_slurm_executor.cpp).
#pragma once

#include <optional>
#include <string>

#include "server/store/catalogue.hpp"

namespace softshock::server {

// How a Slurm job state reads in our model.
struct SlurmOutcome {
  enum class Kind { kWaiting, kRunning, kTerminal, kUnknown } kind = Kind::kUnknown;
  JobState state = JobState::kQueued;  // for kTerminal
  std::string reason;                  // for kTerminal FAILED: SLURM_<STATE>
};
// PENDING (and requeue/hold states) → waiting (QUEUED); RUNNING, COMPLETING, SUSPENDED… →
// running; COMPLETED → SUCCEEDED (once the result is verified); CANCELLED → CANCELLED; TIMEOUT
// (the wall limit) → FAILED WALL_TIME_EXCEEDED; FAILED, OUT_OF_MEMORY, NODE_FAIL, BOOT_FAIL,
// DEADLINE, PREEMPTED → FAILED with reason SLURM_<STATE> (the executor then takes a solver's own
// cause from its result's summary where it names one). Accepts sacct's "CANCELLED by 0" form.
SlurmOutcome map_slurm_state(const std::string& slurm_state);

// The job id of `sbatch --parsable` output ("123" or "123;cluster"); empty if there is none.
std::string parse_sbatch_job_id(const std::string& output);

// A seconds figure for a command line, exact (shortest round-trip form).
std::string end_time_text(double s);
// Surrounding whitespace removed; the first line of s, so trimmed.
std::string trim(const std::string& s);
std::string first_line(const std::string& s);
// POSIX shell single quotes.
std::string sh_quote(const std::string& s);
// The last non-empty line of the solver's stderr that is not a progress line: its own reason for
// failing.
std::string last_line(const std::string& text);
// The last progress line of softshock-solve's stderr, if any.
std::optional<JobProgressRecord> progress_from_log(const std::string& text);

}  // namespace softshock::server
