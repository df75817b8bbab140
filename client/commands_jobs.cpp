// submit, status, watch, list, cancel, delete, summary, health.
#include <google/protobuf/struct.pb.h>
#include <google/protobuf/util/json_util.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstdio>
#include <thread>

#include "client/commands.hpp"
#include "client/format.hpp"
#include "client/spec_diagnostics.hpp"

namespace softshock::cli {

namespace {

int32_t parse_int32(const std::string& option, const std::string& text, int32_t min_value) {
  int64_t v = parse_int(option, text);
  if (v < min_value || v > INT32_MAX) {
    usage_error("--" + option + ": must be between " + std::to_string(min_value) + " and " +
                std::to_string(INT32_MAX));
  }
  return static_cast<int32_t>(v);
}

std::string describe_geometry(const v1::RunSpec& spec) {
  const auto& g = spec.geometry();
  std::string shape;
  switch (g.shape_case()) {
    case v1::Geometry::kDisk:
      shape = "disk R = " + fmt_num(g.disk().radius() * 1e6) + " µm";
      break;
    case v1::Geometry::kRoundedSquare:
      shape = "rounded square " + fmt_num(g.rounded_square().side() * 1e6) + " µm, corner " +
              fmt_num(g.rounded_square().corner_radius() * 1e6) + " µm";
      break;
    case v1::Geometry::kMeshFile:
      return "mesh " + g.mesh_file();
    default:
      shape = "disk (default)";
  }
  return shape + ", ~" + std::to_string(g.target_elements()) + " elements";
}

void print_job(const v1::Job& job) {
  KeyValues kv;
  kv.add("id", job.id());
  kv.add("name", job.name());
  kv.add("state", state_name(job.state()));
  kv.add("owner", job.owner().empty() ? "-" : job.owner());
  const auto& p = job.progress();
  std::string progress =
      fmt_num(p.fraction() * 100.0, 4) + " %  (t = " + fmt_num(p.simulated_time() * 1e9, 5) +
      " of " + fmt_ns(job.spec().run().end_time()) + ", " + std::to_string(p.steps()) + " steps";
  if (p.dt() > 0) progress += ", dt = " + fmt_ns(p.dt());
  kv.add("progress", progress + ")");
  if (!job.reason().empty()) kv.add("reason", job.reason());
  if (!job.error().empty()) kv.add("error", job.error());
  kv.add("geometry", describe_geometry(job.spec()));
  kv.add("end time", fmt_ns(job.spec().run().end_time()));
  kv.add("labels", job.labels().empty() ? "-" : join_labels(job.labels()));
  kv.add("priority", std::to_string(job.priority()));
  kv.add("attempt", std::to_string(job.attempt()));
  kv.add("created", fmt_timestamp(job.create_time()));
  if (timestamp_set(job.start_time())) kv.add("started", fmt_timestamp(job.start_time()));
  if (timestamp_set(job.finish_time())) {
    kv.add("finished", fmt_timestamp(job.finish_time()));
    if (timestamp_set(job.start_time())) {
      kv.add("run time", fmt_duration(timestamp_seconds(job.finish_time()) -
                                      timestamp_seconds(job.start_time())));
    }
  }
  if (!job.result_path().empty()) kv.add("result", job.result_path());
  if (!job.request_id().empty()) kv.add("request id", job.request_id());
  if (!job.spec_hash().empty()) kv.add("spec hash", job.spec_hash());
  kv.print(stdout);
}

const std::string& single_id(const ParsedArgs& a) {
  return a.positional.at(0);
}

}  // namespace

int exit_for_final_state(const v1::Job& job) {
  if (job.state() == v1::SUCCEEDED) return kExitOk;
  std::string message = "job " + job.id() + " " + state_name(job.state());
  if (!job.reason().empty()) message += " (" + job.reason() + ")";
  if (!job.error().empty()) message += ": " + job.error();
  throw CliError(kExitFailure, message);
}

v1::Job watch_until_done(Connection& conn, const std::string& id, bool json) {
  ProgressDisplay display(stdout, json);
  v1::WatchJobRequest request;
  request.set_id(id);
  using Clock = std::chrono::steady_clock;
  // While the daemon is unreachable (a restart), keep trying for --timeout seconds before giving
  // up; --timeout 0 (no deadlines) waits for it indefinitely.
  const bool forever = conn.timeout_s() <= 0;
  const auto patience = std::chrono::milliseconds(static_cast<int64_t>(conn.timeout_s() * 1000));
  auto unreachable_since = Clock::time_point{};
  bool warned = false;
  v1::Job job;
  for (;;) {
    auto ctx = conn.context(/*with_deadline=*/false);
    auto reader = conn.service().WatchJob(ctx.get(), request);
    bool got_any = false;
    while (reader->Read(&job)) {
      got_any = true;
      display.update(job);
      if (is_terminal(job.state())) {
        ctx->TryCancel();  // nothing more to hear; do not wait for the server to close
        break;
      }
    }
    grpc::Status status = reader->Finish();
    if (is_terminal(job.state())) {
      display.finish(job);
      return job;
    }
    if (status.ok() || status.error_code() == grpc::StatusCode::UNAVAILABLE) {
      // A stream that ends without a terminal state means the server went away (shutdown or
      // crash): reconnect, since jobs survive daemon restarts.
      if (got_any || unreachable_since == Clock::time_point{}) unreachable_since = Clock::now();
      if (!forever && Clock::now() - unreachable_since > patience) {
        throw status_error(
            status.ok() ? grpc::Status(grpc::StatusCode::UNAVAILABLE, "watch stream ended early")
                        : status,
            conn.target());
      }
      if (!warned && !json) {
        std::fprintf(stderr, "\nsoftshock: watch: lost the daemon, reconnecting...\n");
        warned = true;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(500));
      continue;
    }
    throw status_error(status, conn.target());
  }
}

int cmd_submit(const GlobalOptions& g, const ParsedArgs& a) {
  const std::string& path = a.positional.at(0);
  v1::SubmitJobRequest request;
  // Options first: a typo in them is reported before the spec file is even opened.
  for (const auto& l : a.all("label")) {
    auto [k, v] = parse_label("label", l);
    (*request.mutable_labels())[k] = v;
  }
  if (auto p = a.get("priority")) request.set_priority(parse_int32("priority", *p, INT32_MIN + 1));
  // Always send a request_id: the connection retries UNAVAILABLE, and the id makes that safe.
  request.set_request_id(a.get("request-id").value_or(make_uuid()));
  bool wait = a.has("wait");

  std::string text = read_file(path);
  google::protobuf::util::JsonParseOptions parse;
  parse.ignore_unknown_fields = false;  // a misspelt field must not silently become a default
  auto st = google::protobuf::util::JsonStringToMessage(text, request.mutable_spec(), parse);
  if (!st.ok()) {
    // Protobuf's parser says "Cannot find field." or "TYPE_DOUBLE"; the schema says more.
    const auto why = explain_json_error(text, v1::RunSpec::descriptor());
    usage_error(path + ": not a valid run spec: " + why.value_or(std::string(st.message())));
  }

  Connection conn(g);
  upload_local_mesh(conn, path, request.mutable_spec());
  v1::Job job;
  conn.unary(
      [&](grpc::ClientContext& ctx) { return conn.service().SubmitJob(&ctx, request, &job); });
  if (g.json) {
    std::printf("%s\n", to_json(job, !wait).c_str());
  } else {
    std::printf("%s\n", job.id().c_str());
  }
  std::fflush(stdout);
  if (!wait) return kExitOk;
  return exit_for_final_state(watch_until_done(conn, job.id(), g.json));
}

int cmd_extend(const GlobalOptions& g, const ParsedArgs& a) {
  v1::ExtendJobRequest request;
  request.set_id(single_id(a));
  const auto end = a.get("end-time");
  if (!end) usage_error("--end-time is required (s, after the job's end time, e.g. 8e-7)");
  request.set_end_time(parse_time_seconds("end-time", *end));
  for (const auto& l : a.all("label")) {
    auto [k, v] = parse_label("label", l);
    (*request.mutable_labels())[k] = v;
  }
  if (auto p = a.get("priority")) request.set_priority(parse_int32("priority", *p, INT32_MIN + 1));
  request.set_request_id(a.get("request-id").value_or(make_uuid()));
  Connection conn(g);
  v1::Job job;
  conn.unary(
      [&](grpc::ClientContext& ctx) { return conn.service().ExtendJob(&ctx, request, &job); });
  if (g.json) {
    std::printf("%s\n", to_json(job, !a.has("wait")).c_str());
  } else {
    std::printf("%s\n", job.id().c_str());
  }
  std::fflush(stdout);
  if (!a.has("wait")) return kExitOk;
  return exit_for_final_state(watch_until_done(conn, job.id(), g.json));
}

int cmd_status(const GlobalOptions& g, const ParsedArgs& a) {
  Connection conn(g);
  v1::GetJobRequest request;
  request.set_id(single_id(a));
  v1::Job job;
  conn.unary([&](grpc::ClientContext& ctx) { return conn.service().GetJob(&ctx, request, &job); });
  if (g.json) {
    std::printf("%s\n", to_json(job).c_str());
  } else {
    print_job(job);
  }
  return kExitOk;
}

int cmd_watch(const GlobalOptions& g, const ParsedArgs& a) {
  Connection conn(g);
  return exit_for_final_state(watch_until_done(conn, single_id(a), g.json));
}

int cmd_cancel(const GlobalOptions& g, const ParsedArgs& a) {
  Connection conn(g);
  v1::CancelJobRequest request;
  request.set_id(single_id(a));
  v1::Job job;
  conn.unary(
      [&](grpc::ClientContext& ctx) { return conn.service().CancelJob(&ctx, request, &job); });
  if (g.json) {
    std::printf("%s\n", to_json(job).c_str());
  } else {
    KeyValues kv;
    kv.add("id", job.id());
    kv.add("state", state_name(job.state()));
    if (!job.reason().empty()) kv.add("reason", job.reason());
    kv.print(stdout);
  }
  return kExitOk;
}

int cmd_delete(const GlobalOptions& g, const ParsedArgs& a) {
  Connection conn(g);
  v1::DeleteJobRequest request;
  request.set_id(single_id(a));
  v1::DeleteJobResponse response;
  conn.unary(
      [&](grpc::ClientContext& ctx) { return conn.service().DeleteJob(&ctx, request, &response); });
  if (g.json) {
    std::printf("%s\n", to_json(response).c_str());
  } else {
    std::printf("deleted: %s\n", single_id(a).c_str());
  }
  return kExitOk;
}

int cmd_summary(const GlobalOptions& g, const ParsedArgs& a) {
  Connection conn(g);
  v1::GetJobSummaryRequest request;
  request.set_id(single_id(a));
  v1::JobSummary s;
  conn.unary(
      [&](grpc::ClientContext& ctx) { return conn.service().GetJobSummary(&ctx, request, &s); });
  if (g.json) {
    // By the proto's names, the ones softshock-solve prints (energy_injected_J_per_m, ...).
    std::printf("%s\n", to_json(s, true, /*proto_names=*/true).c_str());
    return kExitOk;
  }
  const auto& n = s.groups();
  KeyValues kv;
  kv.add("id", s.id());
  kv.add("elements", std::to_string(s.elements()));
  kv.add("nodes", std::to_string(s.nodes()));
  kv.add("steps", std::to_string(s.steps()));
  kv.add("wall time", fmt_num(s.wall_time_s(), 4) + " s");
  kv.add("simulated time", fmt_ns(s.end_time_s()));
  if (s.dimension() == 3) {
    kv.add("dimension", "3 (tetrahedra; per-metre figures over the " +
                            fmt_num(s.thickness_m() * 1e6, 4) + " um thickness)");
  }
  kv.add("solver revision", s.solver_revision() > 0 ? std::to_string(s.solver_revision())
                                                    : std::string("not recorded"));
  if (s.steps() > 0 && s.elements() > 0 && s.wall_time_s() > 0) {
    // Grind time, the figure explicit codes are compared by (LS-DYNA's "time per zone cycle"):
    // the whole run's and the element loop's alone, and the meshing share beside them, so the
    // user sees where the time went.
    kv.add("grind time",
           fmt_num(s.wall_time_s() / (double(s.steps()) * double(s.elements())) * 1e9, 4) +
               " ns per element-step");
    if (s.kernel_time_s() > 0) {
      kv.add("kernel grind time",
             fmt_num(s.kernel_time_s() / (double(s.steps()) * double(s.elements())) * 1e9, 4) +
                 " ns per element-step (element passes alone)");
    }
  }
  if (s.wall_time_s() > 0 && (s.diagnostics_time_s() > 0 || s.output_time_s() > 0)) {
    kv.add("diagnostics", fmt_num(s.diagnostics_time_s(), 3) + " s (" +
                              fmt_num(100 * s.diagnostics_share(), 3) +
                              " % of the run: history samples and frame fields)");
    kv.add("output", fmt_num(s.output_time_s(), 3) + " s (" + fmt_num(100 * s.output_share(), 3) +
                         " % of the run: frames handed to the writer thread)");
  }
  if (!s.mesh_cache().empty()) {
    kv.add("meshing",
           fmt_num(s.meshing_time_s(), 3) + " s (" +
               fmt_num(100 * s.meshing_time_s() / (s.meshing_time_s() + s.wall_time_s()), 3) +
               " % of meshing + run; mesh cache: " + s.mesh_cache() + ")");
  }
  kv.add("time scale R0/c0", fmt_ns(n.time_scale_s()));
  kv.add("P-bar", fmt_num(n.pbar()));
  kv.add("t-bar pulse", fmt_num(n.tbar_pulse()));
  kv.add("mu-bar", fmt_num(n.mubar()));
  kv.add("gamma", fmt_num(n.gamma()));
  kv.add("C1, C2", fmt_num(n.c1()) + ", " + fmt_num(n.c2()));
  kv.add("energy injected", fmt_num(s.energy_injected_j_per_m()) + " J/m");
  kv.add("energy after pulse", fmt_num(s.energy_after_pulse_j_per_m()) + " J/m");
  kv.add("max A-bar (t-bar <= 4)", fmt_num(s.max_abar_first_cycle()));
  kv.add("max A-bar", fmt_num(s.max_abar()));
  kv.add("A-bar at end", fmt_num(s.abar_end()));
  kv.add("filtered A-bar (modes <= 32)",
         "max " + fmt_num(s.max_abar_filtered()) +
             " (t-bar <= 4: " + fmt_num(s.max_abar_filtered_first_cycle()) + "), at end " +
             fmt_num(s.abar_filtered_end()));
  kv.add("max element aspect ratio",
         fmt_num(s.max_aspect_ratio()) +
             (s.aspect_ratio_above_10_s() < 0
                  ? " (never above 10)"
                  : " (above 10 from " + fmt_ns(s.aspect_ratio_above_10_s()) + ")"));
  kv.add("dominant mode at end", std::to_string(s.dominant_mode_end()));
  kv.add("shock at centre",
         s.shock_at_center_s() < 0 ? "not detected" : fmt_ns(s.shock_at_center_s()));
  std::string rims;
  for (double t : s.rim_reflections_s()) rims += (rims.empty() ? "" : ", ") + fmt_num(t * 1e9, 5);
  kv.add("rim reflections", rims.empty() ? "none" : rims + " ns");
  kv.add("dt range", fmt_num(s.min_dt_s() * 1e9, 4) + " .. " + fmt_ns(s.max_dt_s()));
  if (s.damage()) {
    kv.add("damage starts",
           s.damage_onset_s() < 0 ? "never (no d >= 1/2)" : fmt_ns(s.damage_onset_s()));
    kv.add("largest damaged zone", fmt_num(s.max_damaged_volume()) +
                                       " (2-D: area, m^2; 3-D: volume, m^3), radius " +
                                       fmt_num(s.max_damaged_radius_m() * 1e6, 4) + " um");
    kv.add("damage dissipation", fmt_num(s.damage_dissipation_j_per_m()) + " J/m");
    kv.add("crack energy at end", fmt_num(s.crack_energy_j_per_m()) + " J/m");
    kv.add("damage updates",
           std::to_string(s.damage_solves()) + " solves, " + fmt_num(s.damage_time_s(), 3) + " s");
  }
  kv.print(stdout);
  return kExitOk;
}

std::string owner_filter(Connection& conn, const ParsedArgs& a) {
  const auto owner = a.get("owner");
  if (owner && a.has("mine")) usage_error("--owner and --mine: give one of them");
  if (owner) {
    if (owner->empty()) usage_error("--owner: expects a user name");
    return *owner;
  }
  if (!a.has("mine")) return "";
  v1::Caller caller;
  conn.unary([&](grpc::ClientContext& ctx) {
    return conn.service().GetCaller(&ctx, v1::GetCallerRequest(), &caller);
  });
  return caller.user();
}

int cmd_whoami(const GlobalOptions& g, const ParsedArgs&) {
  Connection conn(g);
  v1::Caller caller;
  conn.unary([&](grpc::ClientContext& ctx) {
    return conn.service().GetCaller(&ctx, v1::GetCallerRequest(), &caller);
  });
  if (g.json) {
    std::printf("%s\n", to_json(caller).c_str());
  } else {
    KeyValues kv;
    kv.add("user", caller.user());
    kv.add("role", caller.role());
    kv.print(stdout);
  }
  return kExitOk;
}

int cmd_figures(const GlobalOptions& g, const ParsedArgs& a) {
  Connection conn(g);
  v1::SummaryFigures figures;
  conn.unary([&](grpc::ClientContext& ctx) {
    return conn.service().ListSummaryFigures(&ctx, v1::ListSummaryFiguresRequest(), &figures);
  });
  const bool query = a.has("query"), grid = a.has("grid");
  if (g.json) {
    std::printf("%s\n", to_json(figures).c_str());
    return kExitOk;
  }
  std::vector<std::vector<std::string>> rows;
  for (const auto& f : figures.figures()) {
    if ((query && !f.queryable()) || (grid && !f.grid_quantity())) continue;
    std::string where = f.queryable() ? "query" : "";
    if (f.grid_quantity()) where += where.empty() ? "grid" : ", grid";
    std::string when = f.only_3d() ? "3-D" : f.only_damage() ? "damage" : "";
    rows.push_back({(f.in_groups() ? "groups." : "") + f.name(), f.unit().empty() ? "-" : f.unit(),
                    where.empty() ? "-" : where, when.empty() ? "-" : when, f.meaning()});
  }
  print_table(stdout, {"NAME", "UNIT", "NAMED IN", "ONLY", "MEANING"}, rows);
  if (grid) std::printf("(grid reduce also takes abar_at with --tbar T: A-bar at that t-bar)\n");
  return kExitOk;
}

int cmd_health(const GlobalOptions& g, const ParsedArgs& a) {
  Connection conn(g);
  grpc::health::v1::HealthCheckRequest request;
  request.set_service(a.get("service").value_or(""));
  grpc::health::v1::HealthCheckResponse response;
  // What the daemon warns about its set-up (e.g. a token without TLS): one metadata entry each.
  std::vector<std::string> warnings;
  conn.unary([&](grpc::ClientContext& ctx) {
    grpc::Status s = conn.health().Check(&ctx, request, &response);
    warnings.clear();
    const auto [first, last] = ctx.GetServerInitialMetadata().equal_range("softshock-warning");
    for (auto it = first; it != last; ++it)
      warnings.emplace_back(it->second.data(), it->second.size());
    return s;
  });
  const std::string status =
      grpc::health::v1::HealthCheckResponse_ServingStatus_Name(response.status());
  if (g.json) {
    // HealthCheckResponse's own JSON ({"status": ...}) plus "warnings" when there are any.
    google::protobuf::Struct out;
    (*out.mutable_fields())["status"].set_string_value(status);
    if (!warnings.empty()) {
      auto* list = (*out.mutable_fields())["warnings"].mutable_list_value();
      for (const auto& w : warnings) list->add_values()->set_string_value(w);
    }
    std::printf("%s\n", to_json(out).c_str());
  } else {
    KeyValues kv;
    kv.add("server", conn.target());
    kv.add("status", status);
    for (const auto& w : warnings) kv.add("warning", w);
    kv.print(stdout);
  }
  if (response.status() != grpc::health::v1::HealthCheckResponse::SERVING) {
    throw CliError(kExitFailure, conn.target() + " is " + status);
  }
  return kExitOk;
}

}  // namespace softshock::cli
