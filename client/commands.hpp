// The `softshock` commands. Each parses its own options (the table in softshock_main.cpp),
// opens the connection only once its arguments are valid, and returns the exit code or throws
// CliError.
#pragma once

#include <algorithm>
#include <cstdint>
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
int cmd_list(const GlobalOptions& g, const ParsedArgs& a);  // commands_accounting.cpp
int cmd_cancel(const GlobalOptions& g, const ParsedArgs& a);
int cmd_delete(const GlobalOptions& g, const ParsedArgs& a);
int cmd_summary(const GlobalOptions& g, const ParsedArgs& a);
int cmd_health(const GlobalOptions& g, const ParsedArgs& a);
int cmd_whoami(const GlobalOptions& g, const ParsedArgs& a);
int cmd_figures(const GlobalOptions& g, const ParsedArgs& a);
// The owner a list command filters on: --owner USER, --mine (the caller, asked of the daemon),
// or "" (everyone's).
std::string owner_filter(Connection& conn, const ParsedArgs& a);

// Results (commands_results.cpp).
int cmd_modes(const GlobalOptions& g, const ParsedArgs& a);
int cmd_series(const GlobalOptions& g, const ParsedArgs& a);
int cmd_field(const GlobalOptions& g, const ParsedArgs& a);
// A-bar(t) of the jobs in one PNG (the plotting helper), every k-th sample (0 = all).
void write_abar_png(Connection& conn, const std::vector<std::string>& ids, int32_t every,
                    const std::string& png);

// Result files brought to this machine (commands_fetch.cpp).
int cmd_fetch(const GlobalOptions& g, const ParsedArgs& a);

// Accounting and comparison (commands_accounting.cpp, commands_compare.cpp).
int cmd_label(const GlobalOptions& g, const ParsedArgs& a);
int cmd_extend(const GlobalOptions& g, const ParsedArgs& a);
int cmd_diff(const GlobalOptions& g, const ParsedArgs& a);

// Uploaded meshes (commands_meshes.cpp).
int cmd_mesh(const GlobalOptions& g, const ParsedArgs& a);
// When the spec's geometry.mesh_file names a file on this machine (absolute, or relative to
// the spec file's folder; spec_path "-" = the working directory), uploads it and replaces it by
// geometry.mesh_id. Otherwise the spec is left alone (mesh_file then names a file in the
// daemon's DATA/meshes/).
void upload_local_mesh(Connection& conn, const std::string& spec_path, v1::RunSpec* spec);

// Grids and the result database (commands_grids.cpp).
int cmd_grid(const GlobalOptions& g, const ParsedArgs& a);
int cmd_query(const GlobalOptions& g, const ParsedArgs& a);

// Follows next_page_token until `limit` items (0 = all), asking for at most 1000 per page.
// `call(ctx, request, page)` runs the RPC; `items(response)` returns its mutable repeated field.
template <typename Request, typename Response, typename Call, typename Items>
Response collect_pages(Connection& conn, Request request, int64_t limit, Call call, Items items) {
  Response all;
  auto count = [&] { return static_cast<int64_t>(items(all)->size()); };
  for (;;) {
    request.set_page_size(
        static_cast<int32_t>(limit == 0 ? 1000 : std::min<int64_t>(1000, limit - count())));
    Response page;
    conn.unary([&](grpc::ClientContext& ctx) { return call(ctx, request, page); });
    for (auto& item : *items(page)) {
      if (limit != 0 && count() >= limit) break;
      *items(all)->Add() = std::move(item);
    }
    all.set_next_page_token(page.next_page_token());
    if (page.next_page_token().empty() || (limit != 0 && count() >= limit)) break;
    request.set_page_token(page.next_page_token());
  }
  return all;
}

// Follows a job until it reaches a terminal state, reconnecting when the daemon restarts;
// returns the final job. Shared by `watch` and `submit --wait`.
v1::Job watch_until_done(Connection& conn, const std::string& id, bool json);
// 0 when the job SUCCEEDED; otherwise throws CliError(1) describing how it ended.
int exit_for_final_state(const v1::Job& job);

}  // namespace softshock::cli
