// SimulationService's result RPCs: GetJobSummary, GetTimeSeries, GetModes (bounded reads of
// the result file) and GetField (a field raster streamed in chunks).
#include <grpcpp/grpcpp.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>

#include "server/log.hpp"
#include "server/transport/field_raster.hpp"
#include "server/transport/field_slice.hpp"
#include "server/transport/resource_name.hpp"
#include "server/transport/rpc_guard.hpp"
#include "server/transport/rpc_support.hpp"
#include "server/transport/simulation_service.hpp"
#include "solver/io/result_file.hpp"

namespace softshock::server {

namespace fs = std::filesystem;
using namespace rpc;
using grpc::Status;
using grpc::StatusCode;

namespace {

constexpr int kMaxRasterSide = 2048;
constexpr int64_t kMaxRasterCells = 4'194'304;
constexpr std::size_t kChunkDoubles = 65536;         // 512 KiB per FieldChunk
constexpr std::size_t kMaxUnaryDoubles = 4'000'000;  // 32 MiB per TimeSeries/Modes answer
// A decimated surface: ~1 MB of coordinates and indices by default, ~10 MB at most.
constexpr std::size_t kDefaultSurfaceTriangles = 20'000;
constexpr int kMaxSurfaceTriangles = 200'000;

struct FieldKind {
  bool node;
  int components;
  const char* units;
};
const std::map<std::string, FieldKind>& field_kinds() {
  static const std::map<std::string, FieldKind> kinds = {
      {"J", {false, 1, "1"}},
      {"mean_stress", {false, 1, "Pa"}},
      {"radial_stress", {false, 1, "Pa"}},
      {"hoop_stress", {false, 1, "Pa"}},
      {"von_mises", {false, 1, "Pa"}},
      {"aspect_ratio", {false, 1, "1"}},
      {"displacement", {true, 2, "m"}},  // components: the mesh's dimension
      {"velocity", {true, 2, "m/s"}},
      {"damage", {true, 1, "1"}},  // phase-field d per node: runs with spec.damage only
  };
  return kinds;
}

}  // namespace

// --- Result queries ------------------------------------------------------------------------

Status SimulationService::result_file(const std::string& id, std::string* path) const {
  auto record = catalogue_.get(id);
  if (!record) return not_found(id);
  if (!is_terminal(record->state)) {
    return {StatusCode::FAILED_PRECONDITION,
            "job " + id + " is " + to_string(record->state) + "; results exist once it finished"};
  }
  if (record->result_path.empty() || !fs::exists(record->result_path)) {
    return {StatusCode::FAILED_PRECONDITION,
            "job " + id + " is " + to_string(record->state) + " and has no result file"};
  }
  *path = record->result_path;
  return Status::OK;
}

Status SimulationService::GetJobSummary(grpc::ServerContext* ctx,
                                        const v1::GetJobSummaryRequest* req, v1::JobSummary* resp) {
  return guarded(auth_, ctx, "GetJobSummary", [&]() -> Status {
    std::string id;
    if (Status st = requested_id(*req, "jobs/", &id); !st.ok()) return st;
    return summary(id, resp);
  });
}

Status SimulationService::summary(const std::string& id, v1::JobSummary* resp) {
  auto record = catalogue_.get(id);
  if (!record) return not_found(id);
  if (!is_terminal(record->state)) {
    return {StatusCode::FAILED_PRECONDITION, "job " + id + " is " + to_string(record->state) +
                                                 "; a summary exists once it finished"};
  }
  auto stored = catalogue_.summary(id);
  if (!stored) {
    return {StatusCode::FAILED_PRECONDITION,
            "job " + id + " is " + to_string(record->state) + " and has no summary"};
  }
  fill_summary(id, stored->summary, resp);
  return Status::OK;
}

Status SimulationService::GetTimeSeries(grpc::ServerContext* ctx,
                                        const v1::GetTimeSeriesRequest* req, v1::TimeSeries* resp) {
  return guarded(auth_, ctx, "GetTimeSeries", [&] { return time_series(*req, resp); });
}

Status SimulationService::time_series(const v1::GetTimeSeriesRequest& req, v1::TimeSeries* resp) {
  std::string id, path;
  if (Status st = requested_id(req, "jobs/", &id); !st.ok()) return st;
  if (req.every() < 0) return invalid("every", "must not be negative");
  if (Status s = result_file(id, &path); !s.ok()) return s;
  ResultReader reader(path);
  const auto known = reader.series_names();
  // Each name at most once (a repeated name would be read and sent again), in request order.
  std::vector<std::string> names;
  for (const auto& n : req.names()) {
    if (std::find(known.begin(), known.end(), n) == known.end()) {
      std::string list;
      for (const auto& k : known) list += (list.empty() ? "" : ", ") + k;
      return invalid("names", "unknown series '" + n + "' (known: " + list + ")");
    }
    if (n != "time" && std::find(names.begin(), names.end(), n) == names.end()) names.push_back(n);
  }
  if (req.names().empty()) {
    for (const auto& k : known) {
      if (k != "time") names.push_back(k);
    }
  }
  // The size is known before anything is read, and only the kept samples are read.
  const std::size_t k = req.every() <= 1 ? 1 : static_cast<std::size_t>(req.every());
  const std::size_t samples = reader.dims("/timeseries/time").at(0);
  const std::size_t kept = (samples + k - 1) / k;
  if (kept * (names.size() + 1) > kMaxUnaryDoubles) {
    return {StatusCode::RESOURCE_EXHAUSTED,
            "answer too large (" + std::to_string(kept * (names.size() + 1)) + " values, at most " +
                std::to_string(kMaxUnaryDoubles) + "); ask for fewer names or a larger every"};
  }
  auto read = [&](const std::string& name) {
    ResultReader::Slice slice;
    slice.stride = k;
    slice.rows = std::min(kept, (reader.dims("/timeseries/" + name).at(0) + k - 1) / k);
    return reader.slice("/timeseries/" + name, slice);
  };
  const auto time = read("time");
  resp->mutable_time()->Add(time.begin(), time.end());
  for (const auto& n : names) {
    auto* series = resp->add_series();
    series->set_name(n);
    series->set_units(series_units(n));
    const auto values = read(n);
    series->mutable_values()->Add(values.begin(), values.end());
  }
  return Status::OK;
}

Status SimulationService::GetModes(grpc::ServerContext* ctx, const v1::GetModesRequest* req,
                                   v1::Modes* resp) {
  return guarded(auth_, ctx, "GetModes", [&] { return modes(*req, resp); });
}

Status SimulationService::modes(const v1::GetModesRequest& req, v1::Modes* resp) {
  std::string id, path;
  if (Status st = requested_id(req, "jobs/", &id); !st.ok()) return st;
  if (req.every() < 0) return invalid("every", "must not be negative");
  if (req.mode_min() < 0) return invalid("mode_min", "must not be negative");
  if (req.mode_max() < 0) return invalid("mode_max", "must not be negative");
  if (Status s = result_file(id, &path); !s.ok()) return s;
  ResultReader reader(path);
  const auto shape = reader.dims("/modes/amplitude");
  const std::size_t rows = std::min(shape.at(0), reader.dims("/modes/time").at(0));
  const std::size_t cols = shape.size() > 1 ? shape[1] : 1;
  if (cols == 0 || rows == 0) {
    resp->set_mode_min(req.mode_min());
    return Status::OK;
  }
  const int highest = static_cast<int>(cols) - 1;
  const int lo = req.mode_min();
  const int hi = req.mode_max() == 0 ? highest : req.mode_max();
  if (lo > highest) {
    return invalid("mode_min", "the result stores modes 0.." + std::to_string(highest));
  }
  if (hi > highest || hi < lo) {
    return invalid("mode_max", "must lie in mode_min.." + std::to_string(highest));
  }
  const int count = hi - lo + 1;
  const std::size_t k = req.every() <= 1 ? 1 : static_cast<std::size_t>(req.every());
  const std::size_t kept = (rows + k - 1) / k;
  if (kept * static_cast<std::size_t>(count + 1) > kMaxUnaryDoubles) {
    return {StatusCode::RESOURCE_EXHAUSTED,
            "answer too large (" + std::to_string(kept * static_cast<std::size_t>(count + 1)) +
                " values, at most " + std::to_string(kMaxUnaryDoubles) +
                "); ask for fewer modes or a larger every"};
  }
  // Only the requested rows and modes are read (never the whole dataset).
  ResultReader::Slice slice;
  slice.stride = k;
  slice.rows = kept;
  const auto times = reader.slice("/modes/time", slice);
  slice.col_first = static_cast<std::size_t>(lo);
  slice.col_count = static_cast<std::size_t>(count);
  const auto amplitudes = reader.slice("/modes/amplitude", slice);
  resp->set_mode_min(lo);
  resp->set_mode_count(count);
  resp->mutable_time()->Add(times.begin(), times.end());
  resp->mutable_amplitude()->Add(amplitudes.begin(), amplitudes.end());
  return Status::OK;
}

Status SimulationService::GetField(grpc::ServerContext* ctx, const v1::GetFieldRequest* req,
                                   grpc::ServerWriter<v1::FieldChunk>* writer) {
  return guarded(auth_, ctx, "GetField", [&]() -> Status {
    StreamSlot slot(*this);
    if (!slot.acquired()) {
      return {StatusCode::RESOURCE_EXHAUSTED,
              "too many concurrent streams (" + std::to_string(config_.max_streams) + ")"};
    }
    return field(ctx, *req, writer);
  });
}

Status SimulationService::field(grpc::ServerContext* ctx, const v1::GetFieldRequest& req,
                                grpc::ServerWriter<v1::FieldChunk>* writer) {
  std::string id, path;
  if (Status st = requested_id(req.job(), req.id(), "jobs/", &id); !st.ok()) return st;
  auto kind_it = field_kinds().find(req.name());
  if (kind_it == field_kinds().end()) {
    std::string list;
    for (const auto& [n, k] : field_kinds()) list += (list.empty() ? "" : ", ") + n;
    return invalid("name", "unknown field '" + req.name() + "' (known: " + list + ")");
  }
  FieldKind kind = kind_it->second;
  int every = 1;
  int nx = 0, ny = 0;
  std::size_t max_triangles = kDefaultSurfaceTriangles;
  if (req.sampling_case() == v1::GetFieldRequest::kEvery) {
    if (req.every() < 0) return invalid("every", "must be >= 1");
    every = std::max(1, req.every());
  } else if (req.sampling_case() == v1::GetFieldRequest::kRaster) {
    nx = req.raster().nx();
    ny = req.raster().ny();
    if (nx < 1 || ny < 1) return invalid("raster", "nx and ny must be >= 1");
    if (nx > kMaxRasterSide || ny > kMaxRasterSide ||
        static_cast<int64_t>(nx) * ny > kMaxRasterCells) {
      return {StatusCode::RESOURCE_EXHAUSTED,
              "raster: nx, ny <= " + std::to_string(kMaxRasterSide) +
                  " and nx*ny <= " + std::to_string(kMaxRasterCells)};
    }
  } else if (req.sampling_case() == v1::GetFieldRequest::kSurface) {
    const int asked = req.surface().max_triangles();
    if (asked < 0) return invalid("surface.max_triangles", "must be >= 0 (0 = the default)");
    if (asked > kMaxSurfaceTriangles) {
      return {StatusCode::RESOURCE_EXHAUSTED,
              "surface.max_triangles: at most " + std::to_string(kMaxSurfaceTriangles)};
    }
    if (asked > 0) max_triangles = static_cast<std::size_t>(asked);
  }
  if (Status s = result_file(id, &path); !s.ok()) return s;
  if (req.name() == "damage") {
    const auto stored = catalogue_.summary(id);
    if (!stored || !stored->summary.damage) {
      return {
          StatusCode::FAILED_PRECONDITION,
          "job " + id + " has no damage field: its spec has no phase-field damage (spec.damage)"};
    }
  }
  ResultReader reader(path);
  const auto& frame_times = reader.info().frame_times;
  if (frame_times.empty()) {
    return {StatusCode::FAILED_PRECONDITION, "job " + id + " has no field frames"};
  }
  std::size_t frame = frame_times.size() - 1;
  if (req.when_case() == v1::GetFieldRequest::kFrame) {
    if (req.frame() < 0 || static_cast<std::size_t>(req.frame()) >= frame_times.size()) {
      return invalid("frame", "must lie in 0.." + std::to_string(frame_times.size() - 1));
    }
    frame = static_cast<std::size_t>(req.frame());
  } else if (req.when_case() == v1::GetFieldRequest::kTime) {
    if (!std::isfinite(req.time())) return invalid("time", "must be finite");
    frame = 0;
    for (std::size_t k = 1; k < frame_times.size(); ++k) {
      if (std::abs(frame_times[k] - req.time()) < std::abs(frame_times[frame] - req.time())) {
        frame = k;
      }
    }
  }

  const int dimension = reader.info().dimension;
  if (kind.node && kind.components > 1) kind.components = dimension;  // vectors: the mesh's
  if (dimension != 3 && req.sampling_case() == v1::GetFieldRequest::kSurface) {
    return invalid("surface", "is for 3-D results; this job's is 2-D (use raster or every)");
  }
  if (dimension != 3 && req.has_slice()) {
    return invalid("slice", "is for 3-D results; this job's is 2-D");
  }
  v1::FieldChunk head;
  auto* header = head.mutable_header();
  header->set_name(req.name());
  header->set_frame(static_cast<int32_t>(frame));
  header->set_frame_count(static_cast<int32_t>(frame_times.size()));
  header->set_time(frame_times[frame]);
  header->set_components(kind.components);
  header->set_units(kind.units);
  header->set_dimension(dimension);
  std::vector<double> values = reader.field(frame, req.name());
  if (dimension == 3 && (req.sampling_case() == v1::GetFieldRequest::kRaster ||
                         req.sampling_case() == v1::GetFieldRequest::kSurface)) {
    if (Status st = field_3d(req, reader, frame, kind.components, kind.node, nx, ny, max_triangles,
                             values, header);
        !st.ok()) {
      return st;
    }
  } else if (req.sampling_case() == v1::GetFieldRequest::kRaster) {
    const Mesh mesh = reader.mesh();
    const auto disp = req.name() == "displacement" ? values : reader.field(frame, "displacement");
    if (disp.size() != 2 * mesh.node_count()) {
      return {StatusCode::INTERNAL, "result file: displacement does not match the mesh"};
    }
    std::vector<double> x(mesh.node_count()), y(mesh.node_count());
    for (std::size_t i = 0; i < x.size(); ++i) {
      x[i] = mesh.x[i] + disp[2 * i];
      y[i] = mesh.y[i] + disp[2 * i + 1];
    }
    RasterBox box;
    try {
      values = rasterize(x, y, mesh.triangles, values, kind.components, kind.node, nx, ny, box);
    } catch (const std::length_error& e) {
      return {StatusCode::RESOURCE_EXHAUSTED, e.what()};
    }
    header->set_location("raster");
    header->set_nx(nx);
    header->set_ny(ny);
    header->set_x_min(box.x_min);
    header->set_x_max(box.x_max);
    header->set_y_min(box.y_min);
    header->set_y_max(box.y_max);
  } else {
    header->set_location(kind.node ? "node" : "element");
    header->set_every(every);
    if (every > 1) {
      const std::size_t c = static_cast<std::size_t>(kind.components);
      std::vector<double> kept;
      for (std::size_t item = 0; item * c < values.size();
           item += static_cast<std::size_t>(every)) {
        kept.insert(kept.end(), values.begin() + item * c, values.begin() + (item + 1) * c);
      }
      values.swap(kept);
    }
  }
  header->set_value_count(static_cast<int64_t>(values.size()));
  if (!writer->Write(head)) return {StatusCode::CANCELLED, "client went away"};
  for (std::size_t offset = 0; offset < values.size(); offset += kChunkDoubles) {
    if (ctx->IsCancelled()) return {StatusCode::CANCELLED, "cancelled by the client"};
    const std::size_t end = std::min(values.size(), offset + kChunkDoubles);
    v1::FieldChunk chunk;
    chunk.set_offset(static_cast<int64_t>(offset));
    chunk.mutable_values()->Add(values.begin() + offset, values.begin() + end);
    if (!writer->Write(chunk)) return {StatusCode::CANCELLED, "client went away"};
  }
  return Status::OK;
}

Status SimulationService::field_3d(const v1::GetFieldRequest& req, const ResultReader& reader,
                                   std::size_t frame, int components, bool node_field, int nx,
                                   int ny, std::size_t max_triangles, std::vector<double>& values,
                                   v1::FieldHeader* header) const {
  const Mesh mesh = reader.mesh();
  const auto disp = req.name() == "displacement" ? values : reader.field(frame, "displacement");
  const std::size_t nn = mesh.node_count();
  if (disp.size() != 3 * nn || mesh.z.size() != nn) {
    return {StatusCode::INTERNAL, "result file: displacement does not match the mesh"};
  }
  std::vector<double> x(nn), y(nn), z(nn);
  for (std::size_t i = 0; i < nn; ++i) {
    x[i] = mesh.x[i] + disp[3 * i];
    y[i] = mesh.y[i] + disp[3 * i + 1];
    z[i] = mesh.z[i] + disp[3 * i + 2];
  }
  if (req.sampling_case() == v1::GetFieldRequest::kRaster) {
    const auto& sl = req.slice();
    SlicePlane plane;
    try {
      plane = req.has_slice()
                  ? make_slice_plane({sl.px(), sl.py(), sl.pz()}, {sl.nx(), sl.ny(), sl.nz()})
                  : make_slice_plane({0, 0, 0}, {0, 0, 1});
    } catch (const std::invalid_argument& e) {
      return invalid("slice", e.what());
    }
    const SliceMesh section =
        slice_tetrahedra(x, y, z, mesh.tetrahedra, values, components, node_field, plane);
    if (section.triangles.empty()) {
      return invalid("slice", "the plane does not cut the deformed body");
    }
    RasterBox box;
    try {
      values = rasterize(section.u, section.v, section.triangles, section.values, components,
                         node_field, nx, ny, box);
    } catch (const std::length_error& e) {
      return {StatusCode::RESOURCE_EXHAUSTED, e.what()};
    }
    header->set_location("raster");
    header->set_nx(nx);
    header->set_ny(ny);
    header->set_x_min(box.x_min);
    header->set_x_max(box.x_max);
    header->set_y_min(box.y_min);
    header->set_y_max(box.y_max);
    for (int k = 0; k < 3; ++k) {
      header->add_slice_origin(plane.origin[k]);
      header->add_slice_u(plane.u[k]);
      header->add_slice_v(plane.v[k]);
    }
    return Status::OK;
  }
  // The surface: element fields per boundary face, from the tetrahedron each face bounds.
  std::vector<double> face_values;
  if (!node_field) {
    std::map<std::array<int32_t, 3>, std::size_t> owner;
    for (std::size_t e = 0; e < mesh.tetrahedra.size(); ++e) {
      const auto& t = mesh.tetrahedra[e];
      for (int skip = 0; skip < 4; ++skip) {
        std::array<int32_t, 3> key{};
        for (int k = 0, n = 0; k < 4; ++k)
          if (k != skip) key[n++] = t[k];
        std::sort(key.begin(), key.end());
        owner[key] = e;  // a boundary face has one owner; interior ones are never looked up
      }
    }
    const std::size_t nc = static_cast<std::size_t>(components);
    for (const auto& f : mesh.boundary_faces) {
      std::array<int32_t, 3> key = f;
      std::sort(key.begin(), key.end());
      const std::size_t e = owner.at(key);
      face_values.insert(face_values.end(), values.begin() + e * nc, values.begin() + (e + 1) * nc);
    }
  }
  const SurfaceMesh surface =
      decimated_surface(x, y, z, mesh.boundary_faces, node_field ? values : face_values, components,
                        node_field, max_triangles);
  std::vector<double> out = surface.xyz;
  for (const auto& t : surface.triangles) out.insert(out.end(), t.begin(), t.end());
  out.insert(out.end(), surface.values.begin(), surface.values.end());
  values.swap(out);
  header->set_location("surface");
  header->set_surface_vertices(static_cast<int64_t>(surface.xyz.size() / 3));
  header->set_surface_triangles(static_cast<int64_t>(surface.triangles.size()));
  return Status::OK;
}

}  // namespace softshock::server
