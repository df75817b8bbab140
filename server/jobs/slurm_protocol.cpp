#include "server/jobs/slurm_protocol.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cstdio>
#include <set>
#include <sstream>

namespace softshock::server {

// A seconds figure for a command line, exact (shortest round-trip form).
std::string end_time_text(double s) {
  char buf[32];
  const auto [end, ec] = std::to_chars(buf, buf + sizeof buf, s);
  return ec == std::errc() ? std::string(buf, end) : std::to_string(s);
}

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r\n");
  if (b == std::string::npos) return "";
  return s.substr(b, s.find_last_not_of(" \t\r\n") - b + 1);
}

std::string first_line(const std::string& s) {
  return trim(s.substr(0, s.find('\n')));
}

// POSIX shell single quotes: the only character needing care inside is the quote itself.
std::string sh_quote(const std::string& s) {
  std::string out = "'";
  for (char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

// The last non-empty line of the solver's stderr: its own reason for failing.
std::string last_line(const std::string& text) {
  std::istringstream in(text);
  std::string line, last;
  while (std::getline(in, line)) {
    if (!trim(line).empty() && line.rfind("progress ", 0) != 0) last = trim(line);
  }
  return last;
}

// softshock-solve writes "progress  50%  t = 10.00 ns  step 1234" to stderr (not a terminal)
// every tenth of the run: enough for live progress of a job on the cluster.
std::optional<JobProgressRecord> progress_from_log(const std::string& text) {
  const auto at = text.rfind("progress ");
  if (at == std::string::npos) return std::nullopt;
  double percent = 0, t_ns = 0;
  long long steps = 0;
  if (std::sscanf(text.c_str() + at, "progress %lf%% t = %lf ns step %lld", &percent, &t_ns,
                  &steps) != 3) {
    return std::nullopt;
  }
  JobProgressRecord p;
  p.fraction = std::clamp(percent / 100.0, 0.0, 1.0);
  p.simulated_time_s = t_ns * 1e-9;
  p.steps = steps;
  return p;
}

SlurmOutcome map_slurm_state(const std::string& slurm_state) {
  const std::string s = slurm_state.substr(0, slurm_state.find(' '));  // "CANCELLED by 0"
  SlurmOutcome o;
  static const std::set<std::string> waiting = {"PENDING",      "REQUEUED",      "REQUEUE_FED",
                                                "REQUEUE_HOLD", "RESV_DEL_HOLD", "CONFIGURING"};
  static const std::set<std::string> running = {"RUNNING",  "COMPLETING", "STAGE_OUT", "SIGNALING",
                                                "RESIZING", "SUSPENDED",  "STOPPED"};
  static const std::set<std::string> failed = {"FAILED",    "TIMEOUT",   "OUT_OF_MEMORY",
                                               "NODE_FAIL", "BOOT_FAIL", "DEADLINE",
                                               "PREEMPTED", "REVOKED",   "SPECIAL_EXIT"};
  if (s == "TIMEOUT") {  // sbatch --time carries the daemon's wall limit
    o.kind = SlurmOutcome::Kind::kTerminal;
    o.state = JobState::kFailed;
    o.reason = reason::kWallTimeExceeded;
    return o;
  }
  if (waiting.count(s)) {
    o.kind = SlurmOutcome::Kind::kWaiting;
  } else if (running.count(s)) {
    o.kind = SlurmOutcome::Kind::kRunning;
  } else if (s == "COMPLETED") {
    o.kind = SlurmOutcome::Kind::kTerminal;
    o.state = JobState::kSucceeded;
  } else if (s == "CANCELLED") {
    o.kind = SlurmOutcome::Kind::kTerminal;
    o.state = JobState::kCancelled;
  } else if (failed.count(s)) {
    o.kind = SlurmOutcome::Kind::kTerminal;
    o.state = JobState::kFailed;
    o.reason = "SLURM_" + s;
  }
  return o;
}

std::string parse_sbatch_job_id(const std::string& output) {
  const std::string line = first_line(output);
  const std::string id = line.substr(0, line.find(';'));
  if (id.empty() || !std::all_of(id.begin(), id.end(), ::isdigit)) return "";
  return id;
}

}  // namespace softshock::server
