#include "server/http/dashboard_api.hpp"

#include <httplib.h>

#include <charconv>
#include <cmath>
#include <sstream>

#include "server/http/grpc_bridge.hpp"
#include "server/http/http_listener.hpp"
#include "softshock/v1/service.grpc.pb.h"

namespace softshock::server::http {

namespace {

using httplib::Request;
using httplib::Response;
using Stub = v1::SimulationService::Stub;

constexpr std::chrono::seconds kUnaryDeadline{30};
constexpr std::chrono::seconds kFieldDeadline{60};
constexpr std::size_t kMaxTokenBytes = 1024;  // page tokens

// Runs `body`, answering a bad query parameter with 400.
template <typename F>
void adapted(Response& res, F&& body) {
  try {
    body();
  } catch (const BadParameter& e) {
    set_error(res, 400, "INVALID_ARGUMENT", e.what());
  }
}

// One unary call on behalf of `req`: the request's token, the call, the answer.
template <typename Message, typename Call>
void unary(const Request& req, Response& res, Call&& call) {
  auto ctx = forwarded_context(req, res, kUnaryDeadline);
  if (!ctx) return;
  Message out;
  const grpc::Status status = call(ctx.get(), &out);
  if (!status.ok()) {
    answer_status(res, status);
    return;
  }
  answer_message(res, out);
}

v1::JobState state_param(const Request& req) {
  const std::string name = string_param(req, "state", 32);
  if (name.empty()) return v1::JOB_STATE_UNSPECIFIED;
  v1::JobState state = v1::JOB_STATE_UNSPECIFIED;
  if (!v1::JobState_Parse(name, &state) || state == v1::JOB_STATE_UNSPECIFIED) {
    throw BadParameter("state must be QUEUED, RUNNING, SUCCEEDED, FAILED or CANCELLED");
  }
  return state;
}

std::vector<std::string> split_names(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream in(text);
  for (std::string part; std::getline(in, part, ',');) {
    if (!part.empty()) out.push_back(part);
  }
  return out;
}

void append_number(std::string& out, double v) {
  if (!std::isfinite(v)) {
    out += "null";
    return;
  }
  char buf[32];
  const auto [ptr, ec] = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::general, 6);
  out.append(buf, ec == std::errc() ? ptr : buf);
}

void add_field(std::string& out, const char* key, double v) {
  out += "\"";
  out += key;
  out += "\":";
  append_number(out, v);
  out += ",";
}

void get_field(Stub& stub, const Request& req, Response& res, const std::string& id) {
  v1::GetFieldRequest r;
  r.set_job("jobs/" + id);
  r.set_name(string_param(req, "name", 64).empty() ? "J" : string_param(req, "name", 64));
  if (const std::string frame = req.get_param_value("frame"); !frame.empty()) {
    r.set_frame(int_param(req, "frame", 0, 0, 10'000'000));
  }
  r.mutable_raster()->set_nx(int_param(req, "nx", 200, 1, kMaxRasterSide));
  r.mutable_raster()->set_ny(int_param(req, "ny", 200, 1, kMaxRasterSide));
  auto ctx = forwarded_context(req, res, kFieldDeadline);
  if (!ctx) return;
  auto reader = stub.GetField(ctx.get(), r);
  v1::FieldChunk chunk;
  v1::FieldHeader header;
  std::vector<double> values;
  bool have_header = false;
  // The answer's size is known from the header (a raster of at most 512 x 512 cells of at most
  // 3 components); chunks that do not fit it end the call.
  const std::size_t limit = static_cast<std::size_t>(kMaxRasterSide) * kMaxRasterSide * 3;
  while (reader->Read(&chunk)) {
    if (!have_header) {
      if (!chunk.has_header() || chunk.header().value_count() < 0 ||
          static_cast<std::size_t>(chunk.header().value_count()) > limit) {
        ctx->TryCancel();
        break;
      }
      header = chunk.header();
      values.reserve(static_cast<std::size_t>(header.value_count()));
      have_header = true;
      continue;
    }
    if (chunk.offset() != static_cast<int64_t>(values.size()) ||
        values.size() + static_cast<std::size_t>(chunk.values_size()) >
            static_cast<std::size_t>(header.value_count())) {
      ctx->TryCancel();
      break;
    }
    values.insert(values.end(), chunk.values().begin(), chunk.values().end());
  }
  const grpc::Status status = reader->Finish();
  if (!status.ok()) {
    answer_status(res, status);
    return;
  }
  if (!have_header || values.size() != static_cast<std::size_t>(header.value_count())) {
    set_error(res, 500, "INTERNAL", "the field stream did not carry the values it announced");
    return;
  }
  res.set_header("Cache-Control", "no-store");
  res.set_content(field_json(header, values), "application/json");
}

}  // namespace

std::string field_json(const v1::FieldHeader& header, const std::vector<double>& values) {
  std::string out = "{\"name\":" + json_quote(header.name()) +
                    ",\"units\":" + json_quote(header.units()) +
                    ",\"location\":" + json_quote(header.location()) + ",";
  out += "\"frame\":" + std::to_string(header.frame()) + ",";
  out += "\"frame_count\":" + std::to_string(header.frame_count()) + ",";
  out += "\"components\":" + std::to_string(header.components()) + ",";
  out += "\"dimension\":" + std::to_string(header.dimension()) + ",";
  out += "\"nx\":" + std::to_string(header.nx()) + ",\"ny\":" + std::to_string(header.ny()) + ",";
  add_field(out, "time", header.time());
  add_field(out, "x_min", header.x_min());
  add_field(out, "x_max", header.x_max());
  add_field(out, "y_min", header.y_min());
  add_field(out, "y_max", header.y_max());
  out += "\"values\":[";
  out.reserve(out.size() + values.size() * 10 + 2);
  for (std::size_t i = 0; i < values.size(); ++i) {
    if (i > 0) out += ',';
    append_number(out, values[i]);
  }
  out += "]}";
  return out;
}

void add_dashboard_api(HttpListener& listener, std::shared_ptr<grpc::Channel> channel) {
  std::shared_ptr<Stub> stub = v1::SimulationService::NewStub(channel);

  listener.get("/api/caller", R"(/api/caller)", [stub](const Request& req, Response& res) {
    unary<v1::Caller>(req, res, [&](grpc::ClientContext* ctx, v1::Caller* out) {
      return stub->GetCaller(ctx, v1::GetCallerRequest{}, out);
    });
  });

  listener.get("/api/figures", R"(/api/figures)", [stub](const Request& req, Response& res) {
    unary<v1::SummaryFigures>(req, res, [&](grpc::ClientContext* ctx, v1::SummaryFigures* out) {
      return stub->ListSummaryFigures(ctx, v1::ListSummaryFiguresRequest{}, out);
    });
  });

  listener.get("/api/jobs", R"(/api/jobs)", [stub](const Request& req, Response& res) {
    adapted(res, [&] {
      v1::ListJobsRequest r;
      r.set_state(state_param(req));
      r.set_label(string_param(req, "label"));
      r.set_owner(string_param(req, "owner", 64));
      r.set_page_size(int_param(req, "page_size", 50, 1, kMaxPageSize));
      r.set_page_token(string_param(req, "page_token", kMaxTokenBytes));
      unary<v1::ListJobsResponse>(req, res, [&](grpc::ClientContext* ctx, auto* out) {
        return stub->ListJobs(ctx, r, out);
      });
    });
  });

  listener.get("/api/jobs/{id}", R"(/api/jobs/([^/]+))", [stub](const Request& req, Response& res) {
    v1::GetJobRequest r;
    r.set_name("jobs/" + req.matches[1].str());
    unary<v1::Job>(req, res, [&](grpc::ClientContext* ctx, v1::Job* out) {
      return stub->GetJob(ctx, r, out);
    });
  });

  listener.post("/api/jobs/{id}/cancel", R"(/api/jobs/([^/]+)/cancel)",
                [stub](const Request& req, Response& res) {
                  v1::CancelJobRequest r;
                  r.set_name("jobs/" + req.matches[1].str());
                  unary<v1::Job>(req, res, [&](grpc::ClientContext* ctx, v1::Job* out) {
                    return stub->CancelJob(ctx, r, out);
                  });
                });

  listener.get("/api/jobs/{id}/summary", R"(/api/jobs/([^/]+)/summary)",
               [stub](const Request& req, Response& res) {
                 v1::GetJobSummaryRequest r;
                 r.set_name("jobs/" + req.matches[1].str());
                 unary<v1::JobSummary>(req, res, [&](grpc::ClientContext* ctx, auto* out) {
                   return stub->GetJobSummary(ctx, r, out);
                 });
               });

  listener.get("/api/jobs/{id}/timeseries", R"(/api/jobs/([^/]+)/timeseries)",
               [stub](const Request& req, Response& res) {
                 adapted(res, [&] {
                   v1::GetTimeSeriesRequest r;
                   r.set_name("jobs/" + req.matches[1].str());
                   const auto names = split_names(string_param(req, "names", 512));
                   if (names.empty() || names.size() > static_cast<std::size_t>(kMaxSeriesNames)) {
                     throw BadParameter("names must list 1 to " + std::to_string(kMaxSeriesNames) +
                                        " series, separated by commas");
                   }
                   for (const auto& n : names) r.add_names(n);
                   r.set_every(int_param(req, "every", 1, 1, 1'000'000));
                   unary<v1::TimeSeries>(req, res, [&](grpc::ClientContext* ctx, auto* out) {
                     return stub->GetTimeSeries(ctx, r, out);
                   });
                 });
               });

  listener.get("/api/jobs/{id}/modes", R"(/api/jobs/([^/]+)/modes)",
               [stub](const Request& req, Response& res) {
                 adapted(res, [&] {
                   v1::GetModesRequest r;
                   r.set_name("jobs/" + req.matches[1].str());
                   r.set_every(int_param(req, "every", 1, 1, 1'000'000));
                   r.set_mode_min(int_param(req, "mode_min", 0, 0, 100'000));
                   r.set_mode_max(int_param(req, "mode_max", 0, 0, 100'000));
                   unary<v1::Modes>(req, res, [&](grpc::ClientContext* ctx, v1::Modes* out) {
                     return stub->GetModes(ctx, r, out);
                   });
                 });
               });

  listener.get("/api/jobs/{id}/field", R"(/api/jobs/([^/]+)/field)",
               [stub](const Request& req, Response& res) {
                 adapted(res, [&] { get_field(*stub, req, res, req.matches[1].str()); });
               });

  listener.get("/api/grids", R"(/api/grids)", [stub](const Request& req, Response& res) {
    adapted(res, [&] {
      v1::ListGridsRequest r;
      r.set_owner(string_param(req, "owner", 64));
      r.set_page_size(int_param(req, "page_size", 50, 1, kMaxPageSize));
      r.set_page_token(string_param(req, "page_token", kMaxTokenBytes));
      unary<v1::ListGridsResponse>(req, res, [&](grpc::ClientContext* ctx, auto* out) {
        return stub->ListGrids(ctx, r, out);
      });
    });
  });

  listener.get("/api/grids/{id}", R"(/api/grids/([^/]+))",
               [stub](const Request& req, Response& res) {
                 v1::GetGridRequest r;
                 r.set_name("grids/" + req.matches[1].str());
                 unary<v1::Grid>(req, res, [&](grpc::ClientContext* ctx, v1::Grid* out) {
                   return stub->GetGrid(ctx, r, out);
                 });
               });

  listener.get("/api/grids/{id}/reduction", R"(/api/grids/([^/]+)/reduction)",
               [stub](const Request& req, Response& res) {
                 adapted(res, [&] {
                   v1::GetGridReductionRequest r;
                   r.set_name("grids/" + req.matches[1].str());
                   r.set_quantity(string_param(req, "quantity", 64));
                   if (auto tbar = double_param(req, "tbar")) r.set_tbar(*tbar);
                   unary<v1::GridReduction>(req, res, [&](grpc::ClientContext* ctx, auto* out) {
                     return stub->GetGridReduction(ctx, r, out);
                   });
                 });
               });
}

}  // namespace softshock::server::http
