// The dashboard's JSON endpoints (docs/api.md, "HTTP: dashboard and metrics"): each is a thin
// adapter over one SimulationService RPC, called in-process with the request's bearer token
// (grpc_bridge.hpp), so answers, errors and ownership rules are the RPC's. What this layer adds
// are its own bounds, tighter than the RPCs' (a page of at most 200 jobs, a raster of at most
// 512 x 512 cells, at most 8 series), and a compact JSON form of a field raster for a canvas.
#pragma once

#include <grpcpp/grpcpp.h>

#include <memory>
#include <string>
#include <vector>

#include "softshock/v1/service.pb.h"

namespace softshock::server {

class HttpListener;

namespace http {

inline constexpr int kMaxPageSize = 200;
inline constexpr int kMaxRasterSide = 512;
inline constexpr int kMaxSeriesNames = 8;

// Registers /api/... on `listener`; calls go through `channel` (the daemon's in-process channel).
void add_dashboard_api(HttpListener& listener, std::shared_ptr<grpc::Channel> channel);

// A field raster as JSON: the header's figures and "values" with null for NaN (cells outside the
// body), 6 significant digits.
std::string field_json(const v1::FieldHeader& header, const std::vector<double>& values);

}  // namespace http
}  // namespace softshock::server
