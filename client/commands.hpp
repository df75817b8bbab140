// The `softshock` commands. Each parses its own options (the table in softshock_main.cpp),
// opens the connection only once its arguments are valid, and returns the exit code or throws
// CliError.
#pragma once

#include <string>
#include <vector>

#include "client/cli_common.hpp"
#include "client/connection.hpp"

namespace softshock::cli {

using CommandFn = int (*)(const GlobalOptions&, const ParsedArgs&);

struct Command {
  const char* name;
  const char* synopsis;  // arguments, for the usage text
  const char* help;      // one line
  std::vector<OptionSpec> options;
  std::size_t min_positional;
  std::size_t max_positional;
  CommandFn run;
};

// Jobs (commands_jobs.cpp).
int cmd_submit(const GlobalOptions& g, const ParsedArgs& a);
int cmd_status(const GlobalOptions& g, const ParsedArgs& a);
int cmd_watch(const GlobalOptions& g, const ParsedArgs& a);
int cmd_list(const GlobalOptions& g, const ParsedArgs& a);
int cmd_cancel(const GlobalOptions& g, const ParsedArgs& a);
int cmd_delete(const GlobalOptions& g, const ParsedArgs& a);
int cmd_summary(const GlobalOptions& g, const ParsedArgs& a);
int cmd_health(const GlobalOptions& g, const ParsedArgs& a);

// Results (commands_results.cpp).
int cmd_modes(const GlobalOptions& g, const ParsedArgs& a);
int cmd_series(const GlobalOptions& g, const ParsedArgs& a);
int cmd_field(const GlobalOptions& g, const ParsedArgs& a);

// Follows a job until it reaches a terminal state, reconnecting when the daemon restarts;
// returns the final job. Shared by `watch` and `submit --wait`.
v1::Job watch_until_done(Connection& conn, const std::string& id, bool json);
// 0 when the job SUCCEEDED; otherwise throws CliError(1) describing how it ended.
int exit_for_final_state(const v1::Job& job);

}  // namespace softshock::cli
