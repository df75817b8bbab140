// list and label: the jobs as an accounting table (sacct's columns: state and its reason, elapsed
// time, owner, chosen spec fields; --since/--until; table, CSV or JSON) and labels edited after
// submission (UpdateJobLabels).
#include <google/protobuf/util/time_util.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>

#include "client/commands.hpp"
#include "client/format.hpp"
#include "client/spec_diagnostics.hpp"

namespace softshock::cli {

namespace {

using google::protobuf::FieldDescriptor;
using google::protobuf::util::TimeUtil;

v1::JobState parse_state(const std::string& text) {
  std::string upper;
  for (char c : text) upper += static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  v1::JobState state;
  if (!v1::JobState_Parse(upper, &state) || state == v1::JOB_STATE_UNSPECIFIED) {
    usage_error("--state: unknown state '" + text +
                "' (QUEUED, RUNNING, SUCCEEDED, FAILED, CANCELLED)");
  }
  return state;
}

double now_seconds() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

}  // namespace

google::protobuf::Timestamp parse_when(const std::string& option, const std::string& text) {
  google::protobuf::Timestamp ts;
  // A time ago: 90s, 30min, 2h, 3d, 1w.
  static const std::pair<const char*, double> kAgo[] = {
      {"min", 60}, {"s", 1}, {"h", 3600}, {"d", 86400}, {"w", 604800}};
  for (const auto& [suffix, seconds] : kAgo) {
    const std::string unit = suffix;
    if (text.size() > unit.size() &&
        text.compare(text.size() - unit.size(), unit.size(), unit) == 0 &&
        std::isdigit(static_cast<unsigned char>(text[0]))) {
      const double amount = parse_double(option, text.substr(0, text.size() - unit.size()));
      const double at = now_seconds() - amount * seconds;
      ts.set_seconds(static_cast<int64_t>(std::floor(at)));
      ts.set_nanos(static_cast<int32_t>((at - std::floor(at)) * 1e9));
      return ts;
    }
  }
  // A day (midnight UTC) or an RFC 3339 time.
  std::string rfc3339 = text;
  if (text.size() == 10 && text[4] == '-' && text[7] == '-') rfc3339 += "T00:00:00Z";
  if (!TimeUtil::FromString(rfc3339, &ts)) {
    usage_error("--" + option + ": '" + text +
                "' is not a time: give 2026-12-04, 2026-12-04T17:00:00Z, or an age (30min, 2h, "
                "3d, 1w)");
  }
  return ts;
}

namespace {

// "4.2 s", "3 min 07 s"; "-" before the job started.
std::string elapsed_text(const v1::Job& job, double* seconds) {
  *seconds = -1;
  if (!timestamp_set(job.start_time())) return "-";
  const double end =
      timestamp_set(job.finish_time()) ? timestamp_seconds(job.finish_time()) : now_seconds();
  *seconds = std::max(0.0, end - timestamp_seconds(job.start_time()));
  return fmt_duration(*seconds);
}

struct Column {
  std::string path;
  std::vector<const FieldDescriptor*> fields;
};

std::vector<Column> chosen_fields(const ParsedArgs& a) {
  std::vector<Column> out;
  for (const auto& list : a.all("fields")) {
    std::size_t start = 0;
    for (;;) {
      const std::size_t comma = list.find(',', start);
      const std::string path =
          trim(list.substr(start, comma == std::string::npos ? comma : comma - start));
      if (!path.empty()) {
        out.push_back({path, resolve_field_path(v1::RunSpec::descriptor(), path, "fields")});
      }
      if (comma == std::string::npos) break;
      start = comma + 1;
    }
  }
  return out;
}

}  // namespace

int cmd_list(const GlobalOptions& g, const ParsedArgs& a) {
  v1::ListJobsRequest request;
  if (auto s = a.get("state")) request.set_state(parse_state(*s));
  auto labels = a.all("label");
  if (labels.size() > 1) usage_error("--label: the server filters on one label at a time");
  if (!labels.empty()) {
    auto [k, v] = parse_label("label", labels[0]);
    request.set_label(k + "=" + v);
  }
  if (auto s = a.get("since")) *request.mutable_created_after() = parse_when("since", *s);
  if (auto u = a.get("until")) *request.mutable_created_before() = parse_when("until", *u);
  int64_t limit = 100;
  if (auto l = a.get("limit")) limit = parse_int("limit", *l);
  if (limit < 0) usage_error("--limit: must be >= 0 (0 = no limit)");
  std::string format = g.json ? "json" : a.get("format").value_or("table");
  if (format != "table" && format != "csv" && format != "json") {
    usage_error("--format: '" + format + "' is not one of table, csv, json");
  }
  const std::vector<Column> fields = chosen_fields(a);

  Connection conn(g);
  request.set_owner(owner_filter(conn, a));
  const auto all = collect_pages<v1::ListJobsRequest, v1::ListJobsResponse>(
      conn, request, limit,
      [&](grpc::ClientContext& ctx, const v1::ListJobsRequest& r, v1::ListJobsResponse& page) {
        return conn.service().ListJobs(&ctx, r, &page);
      },
      [](v1::ListJobsResponse& r) { return r.mutable_jobs(); });
  if (format == "json") {
    std::printf("%s\n", to_json(all).c_str());
    return kExitOk;
  }
  const bool csv = format == "csv";
  std::vector<std::string> header =
      csv ? std::vector<std::string>{"id",      "state",   "reason",   "progress", "owner",
                                     "created", "started", "finished", "elapsed_s"}
          : std::vector<std::string>{"ID",      "STATE", "REASON", "PROGRESS",
                                     "ELAPSED", "OWNER", "CREATED"};
  for (const auto& f : fields) header.push_back(f.path);
  header.push_back(csv ? "labels" : "LABELS");
  std::vector<std::vector<std::string>> rows;
  for (const auto& job : all.jobs()) {
    double seconds = -1;
    const std::string elapsed = elapsed_text(job, &seconds);
    const std::string reason = job.reason().empty() ? (csv ? "" : "-") : job.reason();
    const std::string owner = job.owner().empty() ? (csv ? "" : "-") : job.owner();
    std::vector<std::string> row;
    if (csv) {
      row = {job.id(),
             state_name(job.state()),
             reason,
             fmt_exact(job.progress().fraction()),
             owner,
             fmt_timestamp(job.create_time()),
             fmt_timestamp(job.start_time()),
             fmt_timestamp(job.finish_time()),
             seconds < 0 ? "" : fmt_exact(seconds)};
    } else {
      row = {job.id(),
             state_name(job.state()),
             reason,
             fmt_num(job.progress().fraction() * 100.0, 3) + "%",
             elapsed,
             owner,
             fmt_timestamp(job.create_time())};
    }
    for (const auto& f : fields) row.push_back(field_path_value(job.spec(), f.fields));
    row.push_back(job.labels().empty() ? (csv ? "" : "-") : join_labels(job.labels()));
    rows.push_back(std::move(row));
  }
  if (csv) {
    auto print_csv_row = [](const std::vector<std::string>& cells) {
      std::string line;
      for (std::size_t c = 0; c < cells.size(); ++c) {
        if (c > 0) line += ',';
        line += csv_escape(cells[c]);
      }
      std::printf("%s\n", line.c_str());
    };
    print_csv_row(header);
    for (const auto& r : rows) print_csv_row(r);
  } else if (rows.empty()) {
    const bool filtered = request.state() != v1::JOB_STATE_UNSPECIFIED ||
                          !request.label().empty() || !request.owner().empty() ||
                          request.has_created_after() || request.has_created_before();
    std::printf(filtered ? "no jobs match these filters\n"
                         : "no jobs yet (softshock submit SPEC.json)\n");
  } else {
    print_table(stdout, header, rows);
  }
  if (!all.next_page_token().empty()) {
    std::fprintf(stderr, "softshock: list: more jobs than --limit %lld; raise it to see them\n",
                 static_cast<long long>(limit));
  }
  return kExitOk;
}

int cmd_label(const GlobalOptions& g, const ParsedArgs& a) {
  v1::UpdateJobLabelsRequest request;
  request.set_name(a.positional.at(0));
  // k=v sets, -k (or --remove k) removes.
  std::vector<std::string> removals = a.all("remove");
  for (std::size_t i = 1; i < a.positional.size(); ++i) {
    const std::string& word = a.positional[i];
    if (word.size() > 1 && word[0] == '-') {
      removals.push_back(word.substr(1));
    } else {
      auto [k, v] = parse_label("label", word);
      (*request.mutable_set())[k] = v;
    }
  }
  for (const auto& key : removals) {
    if (key.empty() || key.find('=') != std::string::npos) {
      usage_error("'-" + key + "': remove a label by its key alone (-study)");
    }
    request.add_remove(key);
  }
  if (request.set().empty() && request.remove().empty()) {
    usage_error("usage: softshock label ID KEY=VALUE... [-KEY]...");
  }
  Connection conn(g);
  v1::Job job;
  conn.unary([&](grpc::ClientContext& ctx) {
    return conn.service().UpdateJobLabels(&ctx, request, &job);
  });
  if (g.json) {
    std::printf("%s\n", to_json(job).c_str());
  } else {
    std::printf("%s: %s\n", job.id().c_str(),
                job.labels().empty() ? "no labels" : join_labels(job.labels()).c_str());
  }
  return kExitOk;
}

}  // namespace softshock::cli
