// grid (submit, status, list, cancel, reduce) and query: parameter studies and the result
// database.
#include <google/protobuf/util/json_util.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <thread>

#include "client/commands.hpp"
#include "client/format.hpp"
#include "client/plot_helper.hpp"
#include "client/spec_diagnostics.hpp"

namespace softshock::cli {

namespace {

std::string grid_counts_text(const v1::Grid& g) {
  const auto& c = g.counts();
  const int done = c.succeeded() + c.failed() + c.cancelled();
  std::string text = std::to_string(done) + "/" + std::to_string(g.point_count()) + " done";
  if (c.reused() > 0) text += " (" + std::to_string(c.reused()) + " reused)";
  text +=
      ", " + std::to_string(c.running()) + " running, " + std::to_string(c.queued()) + " queued";
  if (c.failed() > 0) text += ", " + std::to_string(c.failed()) + " failed";
  if (c.cancelled() > 0) text += ", " + std::to_string(c.cancelled()) + " cancelled";
  return text;
}

std::string axis_text(const v1::GridAxis& a) {
  std::string values;
  const int n = a.values_size();
  if (n <= 6) {
    for (double v : a.values()) values += (values.empty() ? "" : ", ") + fmt_num(v, 4);
  } else {
    values = fmt_num(a.values(0), 4) + ", " + fmt_num(a.values(1), 4) + ", ..., " +
             fmt_num(a.values(n - 1), 4);
  }
  return a.name() + " (" + std::to_string(n) + "): " + values;
}

void print_grid(const v1::Grid& g) {
  KeyValues kv;
  kv.add("id", g.id());
  kv.add("name", g.name());
  kv.add("state", state_name(g.state()));
  kv.add("owner", g.owner().empty() ? "-" : g.owner());
  kv.add("progress", fmt_num(g.progress() * 100.0, 4) + " %");
  kv.add("points", grid_counts_text(g));
  std::string shape;
  for (int n : g.shape()) shape += (shape.empty() ? "" : " x ") + std::to_string(n);
  kv.add("shape", shape);
  for (int a = 0; a < g.axes_size(); ++a) kv.add("axis " + std::to_string(a), axis_text(g.axes(a)));
  kv.add("created", fmt_timestamp(g.create_time()));
  if (g.cancelled()) kv.add("cancelled", "yes");
  if (g.recompute()) kv.add("recompute", "yes");
  if (!g.request_id().empty()) kv.add("request id", g.request_id());
  kv.print(stdout);
}

v1::Grid get_grid(Connection& conn, const std::string& id) {
  v1::GetGridRequest request;
  request.set_id(id);
  v1::Grid grid;
  conn.unary(
      [&](grpc::ClientContext& ctx) { return conn.service().GetGrid(&ctx, request, &grid); });
  return grid;
}

// Polls the grid once a second until every point finished (grids have no watch stream: a
// 121-point grid changes too often to be worth streaming). A line per change on a terminal,
// at most every 5 s otherwise; with json, the final grid only.
v1::Grid wait_grid(Connection& conn, const std::string& id, bool json) {
  using Clock = std::chrono::steady_clock;
  const bool tty = isatty(fileno(stdout)) != 0;
  std::string last;
  auto last_print = Clock::time_point{};
  for (;;) {
    v1::Grid g = get_grid(conn, id);
    const bool done = is_terminal(g.state());
    const std::string line = "grid " + g.id() + " " + state_name(g.state()) + " " +
                             fmt_num(g.progress() * 100.0, 3) + " %: " + grid_counts_text(g);
    if (!json && line != last &&
        (done || tty || Clock::now() - last_print > std::chrono::seconds(5))) {
      std::printf("%s\n", line.c_str());
      std::fflush(stdout);
      last = line;
      last_print = Clock::now();
    }
    if (done) return g;
    std::this_thread::sleep_for(std::chrono::seconds(1));
  }
}

int grid_exit(const v1::Grid& g) {
  if (g.state() == v1::SUCCEEDED) return kExitOk;
  throw CliError(kExitFailure,
                 "grid " + g.id() + " " + state_name(g.state()) + ": " + grid_counts_text(g));
}

int grid_submit(const GlobalOptions& g, const ParsedArgs& a) {
  if (a.positional.size() != 2) usage_error("usage: softshock grid submit GRID.json [--wait]");
  const std::string& path = a.positional[1];
  v1::SubmitGridRequest request;
  const std::string text = read_file(path);
  google::protobuf::util::JsonParseOptions parse;
  parse.ignore_unknown_fields = false;  // a misspelt field must not silently become a default
  auto st = google::protobuf::util::JsonStringToMessage(text, &request, parse);
  if (!st.ok()) {
    const auto why = explain_json_error(text, v1::SubmitGridRequest::descriptor());
    usage_error(path + ": not a valid grid (SubmitGridRequest JSON): " +
                why.value_or(std::string(st.message())));
  }
  for (const auto& l : a.all("label")) {
    auto [k, v] = parse_label("label", l);
    (*request.mutable_labels())[k] = v;
  }
  if (auto p = a.get("priority")) {
    const int64_t v = parse_int("priority", *p);
    if (v < INT32_MIN + 1 || v > INT32_MAX) usage_error("--priority: out of range");
    request.set_priority(static_cast<int32_t>(v));
  }
  if (a.has("recompute")) request.set_recompute(true);
  // Always a request_id: the connection retries UNAVAILABLE, and the id makes that safe.
  request.set_request_id(
      a.get("request-id")
          .value_or(request.request_id().empty() ? make_uuid() : request.request_id()));
  Connection conn(g);
  upload_local_mesh(conn, path, request.mutable_base_spec());
  v1::Grid grid;
  conn.unary(
      [&](grpc::ClientContext& ctx) { return conn.service().SubmitGrid(&ctx, request, &grid); });
  if (!a.has("wait")) {
    std::printf("%s\n", g.json ? to_json(grid).c_str() : grid.id().c_str());
    return kExitOk;
  }
  if (!g.json) std::printf("%s\n", grid.id().c_str());
  std::fflush(stdout);
  grid = wait_grid(conn, grid.id(), g.json);
  if (g.json) std::printf("%s\n", to_json(grid).c_str());
  return grid_exit(grid);
}

// Coordinates (index along each axis) of flat point index i, last axis fastest.
std::vector<int> point_coordinates(const v1::GridReduction& r, int i) {
  std::vector<int> at(r.axes_size(), 0);
  for (int k = r.axes_size() - 1; k >= 0; --k) {
    at[k] = i % std::max(1, r.shape(k));
    i /= std::max(1, r.shape(k));
  }
  return at;
}

// A reduction as a table: a matrix for two axes (rows: the first axis), one row per point
// otherwise.
void print_reduction_table(const v1::GridReduction& r) {
  const std::string head =
      r.quantity() + (r.quantity() == "abar_at" ? " (t-bar = " + fmt_num(r.tbar()) + ")" : "") +
      " [" + r.units() + "]";
  std::printf("# %s\n", head.c_str());
  std::vector<std::vector<std::string>> rows;
  if (r.axes_size() == 2) {
    const auto& x = r.axes(0);
    const auto& y = r.axes(1);
    std::vector<std::string> header = {x.name() + " \\ " + y.name()};
    for (double v : y.values()) header.push_back(fmt_num(v, 4));
    for (int i = 0; i < x.values_size(); ++i) {
      std::vector<std::string> row = {fmt_num(x.values(i), 4)};
      for (int j = 0; j < y.values_size(); ++j) {
        row.push_back(fmt_num(r.values(i * y.values_size() + j), 4));
      }
      rows.push_back(std::move(row));
    }
    print_table(stdout, header, rows);
    return;
  }
  std::vector<std::string> header;
  for (const auto& axis : r.axes()) header.push_back(axis.name());
  header.push_back(r.quantity());
  header.push_back("job");
  header.push_back("state");
  for (int i = 0; i < r.values_size(); ++i) {
    const auto at = point_coordinates(r, i);
    std::vector<std::string> row;
    for (int k = 0; k < r.axes_size(); ++k) row.push_back(fmt_num(r.axes(k).values(at[k]), 6));
    row.push_back(fmt_num(r.values(i), 6));
    row.push_back(i < r.job_ids_size() ? r.job_ids(i) : "");
    row.push_back(i < r.states_size() ? state_name(r.states(i)) : "");
    rows.push_back(std::move(row));
  }
  print_table(stdout, header, rows);
}

// Long format: one line per point with its coordinates, value, job and state.
void print_reduction_csv(const v1::GridReduction& r) {
  std::string line;
  for (const auto& axis : r.axes()) line += csv_escape(axis.name()) + ",";
  line += csv_escape(r.quantity()) + ",job_id,state";
  std::printf("%s\n", line.c_str());
  for (int i = 0; i < r.values_size(); ++i) {
    const auto at = point_coordinates(r, i);
    line.clear();
    for (int k = 0; k < r.axes_size(); ++k) line += fmt_exact(r.axes(k).values(at[k])) + ",";
    line += fmt_exact(r.values(i)) + ",";
    line += (i < r.job_ids_size() ? r.job_ids(i) : "") + ",";
    line += i < r.states_size() ? state_name(r.states(i)) : "";
    std::printf("%s\n", line.c_str());
  }
}

int grid_reduce(const GlobalOptions& g, const ParsedArgs& a) {
  if (a.positional.size() != 2) usage_error("usage: softshock grid reduce ID [--quantity Q]");
  v1::GetGridReductionRequest request;
  request.set_id(a.positional[1]);
  request.set_quantity(a.get("quantity").value_or(""));
  if (auto t = a.get("tbar")) request.set_tbar(parse_double("tbar", *t));
  Connection conn(g);
  v1::GridReduction r;
  conn.unary(
      [&](grpc::ClientContext& ctx) { return conn.service().GetGridReduction(&ctx, request, &r); });
  if (auto png = a.get("png")) {
    TempDir tmp;
    const std::string json = tmp.path() + "/reduction.json";
    write_text_file(json, to_json(r, false));
    run_python_plot({"grid-heatmap", "--json=" + json, "--out=" + *png});
    std::fprintf(stderr, "wrote %s\n", png->c_str());
  }
  if (g.json) {
    std::printf("%s\n", to_json(r).c_str());
  } else if (a.has("csv")) {
    print_reduction_csv(r);
  } else if (!a.has("png")) {
    print_reduction_table(r);
  }
  return kExitOk;
}

int grid_list(const GlobalOptions& g, const ParsedArgs& a) {
  Connection conn(g);
  v1::ListGridsRequest request;
  request.set_page_size(1000);
  request.set_owner(owner_filter(conn, a));
  v1::ListGridsResponse all;
  for (;;) {
    v1::ListGridsResponse page;
    conn.unary(
        [&](grpc::ClientContext& ctx) { return conn.service().ListGrids(&ctx, request, &page); });
    for (auto& grid : *page.mutable_grids()) *all.add_grids() = std::move(grid);
    if (page.next_page_token().empty()) break;
    request.set_page_token(page.next_page_token());
  }
  if (g.json) {
    std::printf("%s\n", to_json(all).c_str());
    return kExitOk;
  }
  std::vector<std::vector<std::string>> rows;
  for (const auto& grid : all.grids()) {
    std::string axes;
    for (const auto& axis : grid.axes()) axes += (axes.empty() ? "" : " x ") + axis.name();
    rows.push_back({grid.id(), state_name(grid.state()), fmt_num(grid.progress() * 100.0, 3) + "%",
                    std::to_string(grid.point_count()), axes,
                    grid.owner().empty() ? "-" : grid.owner(), fmt_timestamp(grid.create_time())});
  }
  print_table(stdout, {"ID", "STATE", "PROGRESS", "POINTS", "AXES", "OWNER", "CREATED"}, rows);
  return kExitOk;
}

// "NAME>=V", "NAME>V", "NAME<=V", "NAME<V", "NAME=V" (equal within 1e-9 relative) or
// "NAME=A..B" (inclusive).
v1::RangeFilter parse_where(const std::string& text) {
  const auto op_at = text.find_first_of("<>=");
  if (op_at == std::string::npos || op_at == 0) {
    usage_error("--where: expected NAME OP VALUE (OP one of < <= > >= =, or NAME=A..B), got '" +
                text + "'");
  }
  v1::RangeFilter f;
  f.set_name(trim(text.substr(0, op_at)));
  std::string op(1, text[op_at]);
  std::size_t value_at = op_at + 1;
  if (value_at < text.size() && text[value_at] == '=') {
    op += '=';
    ++value_at;
  }
  const std::string value = trim(text.substr(value_at));
  if (op == "=" || op == "==") {
    if (const auto dots = value.find(".."); dots != std::string::npos) {
      f.set_ge(parse_double("where", trim(value.substr(0, dots))));
      f.set_le(parse_double("where", trim(value.substr(dots + 2))));
    } else {
      const double v = parse_double("where", value);
      f.set_ge(v - 1e-9 * std::abs(v));
      f.set_le(v + 1e-9 * std::abs(v));
    }
  } else if (op == ">") {
    f.set_gt(parse_double("where", value));
  } else if (op == ">=") {
    f.set_ge(parse_double("where", value));
  } else if (op == "<") {
    f.set_lt(parse_double("where", value));
  } else if (op == "<=") {
    f.set_le(parse_double("where", value));
  } else {
    usage_error("--where: unknown operator in '" + text + "'");
  }
  return f;
}

std::string value_or_dash(double v) {
  return std::isnan(v) ? "-" : fmt_num(v, 4);
}

}  // namespace

int cmd_grid(const GlobalOptions& g, const ParsedArgs& a) {
  const std::string& sub = a.positional.at(0);
  if (sub == "submit") return grid_submit(g, a);
  if (sub == "reduce") return grid_reduce(g, a);
  if (sub == "list") return grid_list(g, a);
  if (sub == "status" || sub == "cancel" || sub == "wait") {
    if (a.positional.size() != 2) usage_error("usage: softshock grid " + sub + " ID");
    Connection conn(g);
    v1::Grid grid;
    if (sub == "cancel") {
      v1::CancelGridRequest request;
      request.set_id(a.positional[1]);
      conn.unary([&](grpc::ClientContext& ctx) {
        return conn.service().CancelGrid(&ctx, request, &grid);
      });
    } else if (sub == "wait") {
      grid = wait_grid(conn, a.positional[1], g.json);
    } else {
      grid = get_grid(conn, a.positional[1]);
    }
    if (g.json) {
      std::printf("%s\n", to_json(grid).c_str());
    } else if (sub != "wait") {
      print_grid(grid);
    }
    return sub == "wait" ? grid_exit(grid) : kExitOk;
  }
  usage_error("grid: unknown subcommand '" + sub +
              "' (submit, status, wait, list, cancel, reduce)");
}

int cmd_query(const GlobalOptions& g, const ParsedArgs& a) {
  v1::QueryJobsRequest request;
  for (const auto& w : a.all("where")) *request.add_filters() = parse_where(w);
  if (auto s = a.get("state")) {
    std::string upper;
    for (char c : *s) upper += static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    v1::JobState state;
    if (!v1::JobState_Parse(upper, &state) || state == v1::JOB_STATE_UNSPECIFIED) {
      usage_error("--state: unknown state '" + *s + "'");
    }
    request.set_state(state);
  }
  if (auto grid = a.get("grid")) request.set_grid_id(*grid);
  if (auto order = a.get("order-by")) request.set_order_by(*order);
  int64_t limit = 100;
  if (auto l = a.get("limit")) limit = parse_int("limit", *l);
  if (limit < 0) usage_error("--limit: must be >= 0 (0 = no limit)");

  Connection conn(g);
  request.set_owner(owner_filter(conn, a));
  const auto all = collect_pages<v1::QueryJobsRequest, v1::QueryJobsResponse>(
      conn, request, limit,
      [&](grpc::ClientContext& ctx, const v1::QueryJobsRequest& r, v1::QueryJobsResponse& page) {
        return conn.service().QueryJobs(&ctx, r, &page);
      },
      [](v1::QueryJobsResponse& r) { return r.mutable_jobs(); });
  if (g.json) {
    std::printf("%s\n", to_json(all).c_str());
    return kExitOk;
  }
  const bool csv = a.has("csv");
  const std::vector<std::string> header = {"id",
                                           "state",
                                           "pbar",
                                           "tbar_pulse",
                                           "mubar",
                                           "gamma",
                                           "c1",
                                           "c2",
                                           "max_abar_first_cycle",
                                           "max_abar",
                                           "dominant_mode_end",
                                           "energy_injected_J_per_m",
                                           "grid_id",
                                           "grid_index",
                                           "reused_from",
                                           "owner"};
  std::vector<std::vector<std::string>> rows;
  for (const auto& q : all.jobs()) {
    const auto& gr = q.groups();
    const bool has = q.has_summary();
    const auto& s = q.summary();
    auto num = [&](double v) { return csv ? fmt_exact(v) : value_or_dash(v); };
    rows.push_back(
        {q.job().id(), state_name(q.job().state()), num(gr.pbar()), num(gr.tbar_pulse()),
         num(gr.mubar()), num(gr.gamma()), num(gr.c1()), num(gr.c2()),
         has ? num(s.max_abar_first_cycle()) : (csv ? "" : "-"),
         has ? num(s.max_abar()) : (csv ? "" : "-"),
         has ? std::to_string(s.dominant_mode_end()) : (csv ? "" : "-"),
         has ? num(s.energy_injected_j_per_m()) : (csv ? "" : "-"),
         q.job().grid_id().empty() ? (csv ? "" : "-") : q.job().grid_id(),
         q.job().grid_id().empty() ? (csv ? "" : "-") : std::to_string(q.job().grid_index()),
         q.job().reused_from().empty() ? (csv ? "" : "-") : q.job().reused_from(),
         q.job().owner().empty() ? (csv ? "" : "-") : q.job().owner()});
  }
  if (csv) {
    // Cells joined one by one (GCC 12 flags `"," + std::string` in a loop with a false
    // -Wrestrict).
    auto print_csv_line = [](const std::vector<std::string>& cells) {
      std::string line;
      for (const auto& cell : cells) {
        if (!line.empty()) line += ',';
        line += csv_escape(cell);
      }
      std::printf("%s\n", line.c_str());
    };
    print_csv_line(header);
    for (const auto& row : rows) print_csv_line(row);
  } else {
    print_table(stdout, header, rows);
  }
  if (!all.next_page_token().empty()) {
    std::fprintf(stderr, "softshock: query: more jobs than --limit %lld; raise it to see them\n",
                 static_cast<long long>(limit));
  }
  return kExitOk;
}

}  // namespace softshock::cli
