// modes, series, field: reading a finished (or running) job's results.
#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <thread>

#include "client/commands.hpp"
#include "client/format.hpp"
#include "client/plot_helper.hpp"

namespace softshock::cli {

namespace {

int32_t parse_nonneg_int32(const std::string& option, const std::string& text) {
  int64_t v = parse_int(option, text);
  if (v < 0 || v > INT32_MAX) usage_error("--" + option + ": must be a non-negative integer");
  return static_cast<int32_t>(v);
}

int32_t parse_every(const ParsedArgs& a) {
  if (auto e = a.get("every")) {
    int32_t k = parse_nonneg_int32("every", *e);
    if (k < 1) usage_error("--every: must be >= 1");
    return k;
  }
  return 0;
}

// A JSON array of doubles; NaN as Python's json module writes it.
std::string json_array(const google::protobuf::RepeatedField<double>& values) {
  std::string out = "[";
  for (double v : values) {
    if (out.size() > 1) out += ',';
    out += std::isfinite(v) ? fmt_exact(v) : "NaN";
  }
  return out + "]";
}

// R0/c0 of a finished job (its summary), to plot against t-bar; 0 when it has no summary.
double time_scale(Connection& conn, const std::string& id) {
  v1::GetJobSummaryRequest request;
  request.set_id(id);
  v1::JobSummary summary;
  try {
    conn.unary([&](grpc::ClientContext& ctx) {
      return conn.service().GetJobSummary(&ctx, request, &summary);
    });
  } catch (const CliError&) {
    return 0.0;
  }
  return summary.groups().time_scale_s();
}

// A-bar(t) of every job given, in one PNG (against t-bar when they share R0/c0).
int series_png(const GlobalOptions& g, const ParsedArgs& a, const std::string& png) {
  if (a.has("csv") || a.has("name")) usage_error("--png plots A-bar(t): no --csv or --name");
  const int32_t every = parse_every(a);
  Connection conn(g);
  write_abar_png(conn, a.positional, every, png);
  std::printf("wrote: %s\n", png.c_str());
  return kExitOk;
}

}  // namespace

void write_abar_png(Connection& conn, const std::vector<std::string>& ids, int32_t every,
                    const std::string& png) {
  std::string series_json;
  double common_scale = -1;
  for (const auto& id : ids) {
    v1::GetTimeSeriesRequest request;
    request.set_id(id);
    request.set_every(every);
    request.add_names("abar");
    v1::TimeSeries ts;
    conn.unary(
        [&](grpc::ClientContext& ctx) { return conn.service().GetTimeSeries(&ctx, request, &ts); });
    if (ts.series_size() != 1 || ts.series(0).values_size() != ts.time_size()) {
      throw CliError(kExitFailure, "job " + id + ": no A-bar series");
    }
    const double scale = time_scale(conn, id);
    common_scale = common_scale < 0 || common_scale == scale ? scale : 0.0;
    series_json += (series_json.empty() ? "" : ",") + std::string("{\"label\":\"") + id +
                   "\",\"time\":" + json_array(ts.time()) +
                   ",\"abar\":" + json_array(ts.series(0).values()) + "}";
  }
  TempDir tmp;
  const std::string json = tmp.path() + "/abar.json";
  write_text_file(json, "{\"series\":[" + series_json +
                            "],\"time_scale\":" + fmt_exact(std::max(0.0, common_scale)) + "}");
  run_python_plot({"abar", "--json=" + json, "--out=" + png});
}

int cmd_modes(const GlobalOptions& g, const ParsedArgs& a) {
  v1::GetModesRequest request;
  request.set_id(a.positional.at(0));
  request.set_every(parse_every(a));
  if (auto m = a.get("mode-min")) request.set_mode_min(parse_nonneg_int32("mode-min", *m));
  if (auto m = a.get("mode-max")) {
    request.set_mode_max(parse_nonneg_int32("mode-max", *m));
    if (request.mode_max() < request.mode_min()) usage_error("--mode-max is below --mode-min");
  }
  Connection conn(g);
  v1::Modes modes;
  conn.unary(
      [&](grpc::ClientContext& ctx) { return conn.service().GetModes(&ctx, request, &modes); });
  const std::size_t rows = static_cast<std::size_t>(modes.time_size());
  const std::size_t cols = static_cast<std::size_t>(std::max(0, modes.mode_count()));
  if (static_cast<std::size_t>(modes.amplitude_size()) != rows * cols) {
    throw CliError(kExitFailure, "server sent " + std::to_string(modes.amplitude_size()) +
                                     " amplitudes for " + std::to_string(rows) + " x " +
                                     std::to_string(cols) + " (inconsistent reply)");
  }
  if (auto png = a.get("png")) {
    if (rows == 0 || cols == 0) throw CliError(kExitFailure, "the job stored no mode amplitudes");
    TempDir tmp;
    write_npy(tmp.path() + "/time.npy", {modes.time().begin(), modes.time().end()}, {rows});
    write_npy(tmp.path() + "/amplitude.npy", {modes.amplitude().begin(), modes.amplitude().end()},
              {rows, cols});
    run_python_plot({"modes", "--time-npy=" + tmp.path() + "/time.npy",
                     "--amplitude-npy=" + tmp.path() + "/amplitude.npy",
                     "--mode-min=" + std::to_string(modes.mode_min()),
                     "--time-scale=" + fmt_exact(time_scale(conn, request.id())),
                     "--title=Rim Fourier modes, job " + request.id(), "--out=" + *png});
    std::printf("wrote: %s\n", png->c_str());
    return kExitOk;
  }
  if (g.json) {
    std::printf("%s\n", to_json(modes).c_str());
    return kExitOk;
  }
  if (a.has("csv")) {
    std::string line = "time";
    for (std::size_t c = 0; c < cols; ++c) line += ",mode_" + std::to_string(modes.mode_min() + c);
    std::printf("%s\n", line.c_str());
    for (std::size_t r = 0; r < rows; ++r) {
      line = fmt_exact(modes.time(static_cast<int>(r)));
      for (std::size_t c = 0; c < cols; ++c) {
        line.append(",").append(fmt_exact(modes.amplitude(static_cast<int>(r * cols + c))));
      }
      std::printf("%s\n", line.c_str());
    }
    return kExitOk;
  }
  std::vector<std::string> header = {"t (ns)"};
  for (std::size_t c = 0; c < cols; ++c)
    header.push_back("m=" + std::to_string(modes.mode_min() + c));
  std::vector<std::vector<std::string>> table;
  for (std::size_t r = 0; r < rows; ++r) {
    std::vector<std::string> row = {fmt_num(modes.time(static_cast<int>(r)) * 1e9, 5)};
    for (std::size_t c = 0; c < cols; ++c) {
      row.push_back(fmt_num(modes.amplitude(static_cast<int>(r * cols + c)), 4));
    }
    table.push_back(std::move(row));
  }
  std::printf("# Fourier amplitudes of the rim radial displacement / R0\n");
  print_table(stdout, header, table);
  return kExitOk;
}

int cmd_series(const GlobalOptions& g, const ParsedArgs& a) {
  if (auto png = a.get("png")) return series_png(g, a, *png);
  if (a.positional.size() > 1) usage_error("several IDs need --png (A-bar(t) of each in one plot)");
  v1::GetTimeSeriesRequest request;
  request.set_id(a.positional.at(0));
  request.set_every(parse_every(a));
  for (const auto& n : a.all("name")) request.add_names(n);
  Connection conn(g);
  v1::TimeSeries ts;
  conn.unary(
      [&](grpc::ClientContext& ctx) { return conn.service().GetTimeSeries(&ctx, request, &ts); });
  for (const auto& s : ts.series()) {
    if (s.values_size() != ts.time_size()) {
      throw CliError(kExitFailure, "series " + s.name() + " has " +
                                       std::to_string(s.values_size()) + " values for " +
                                       std::to_string(ts.time_size()) + " times");
    }
  }
  if (g.json) {
    std::printf("%s\n", to_json(ts).c_str());
    return kExitOk;
  }
  if (a.has("csv")) {
    std::string line = "time";
    for (const auto& s : ts.series()) line += "," + csv_escape(s.name());
    std::printf("%s\n", line.c_str());
    for (int r = 0; r < ts.time_size(); ++r) {
      line = fmt_exact(ts.time(r));
      for (const auto& s : ts.series()) line.append(",").append(fmt_exact(s.values(r)));
      std::printf("%s\n", line.c_str());
    }
    return kExitOk;
  }
  std::vector<std::string> header = {"t (ns)"};
  for (const auto& s : ts.series()) {
    header.push_back(s.units().empty() ? s.name() : s.name() + " (" + s.units() + ")");
  }
  std::vector<std::vector<std::string>> table;
  for (int r = 0; r < ts.time_size(); ++r) {
    std::vector<std::string> row = {fmt_num(ts.time(r) * 1e9, 5)};
    for (const auto& s : ts.series()) row.push_back(fmt_num(s.values(r), 5));
    table.push_back(std::move(row));
  }
  print_table(stdout, header, table);
  return kExitOk;
}

namespace {

struct FieldData {
  v1::FieldHeader header;
  std::vector<double> values;
};

FieldData fetch_field(Connection& conn, const v1::GetFieldRequest& request) {
  // A server stream cannot be retried half-way by the generic helper: retry the whole call on
  // UNAVAILABLE only before any chunk arrived.
  for (int attempt = 1;; ++attempt) {
    auto ctx = conn.context();
    auto reader = conn.service().GetField(ctx.get(), request);
    FieldData field;
    v1::FieldChunk chunk;
    bool have_header = false;
    std::vector<bool> filled;  // catches gaps or overlaps in the chunk offsets
    std::size_t filled_count = 0;
    std::string protocol_error;
    while (reader->Read(&chunk)) {
      if (chunk.has_header()) {
        field.header = chunk.header();
        if (field.header.value_count() < 0 || field.header.value_count() > (int64_t(1) << 31)) {
          protocol_error = "bad value_count " + std::to_string(field.header.value_count());
          break;
        }
        field.values.assign(static_cast<std::size_t>(field.header.value_count()), std::nan(""));
        filled.assign(field.values.size(), false);
        have_header = true;
      }
      if (!have_header) {
        protocol_error = "values before the header";
        break;
      }
      const auto offset = chunk.offset();
      if (offset < 0 ||
          static_cast<std::size_t>(offset) + chunk.values_size() > field.values.size()) {
        protocol_error = "chunk at offset " + std::to_string(offset) + " overruns the field";
        break;
      }
      for (int i = 0; i < chunk.values_size(); ++i) {
        std::size_t at = static_cast<std::size_t>(offset) + i;
        field.values[at] = chunk.values(i);
        if (!filled[at]) ++filled_count;
        filled[at] = true;
      }
    }
    if (!protocol_error.empty()) {
      ctx->TryCancel();
      reader->Finish();
      throw CliError(kExitFailure, "field stream: " + protocol_error);
    }
    grpc::Status status = reader->Finish();
    if (status.ok()) {
      if (!have_header) throw CliError(kExitFailure, "field stream: no header");
      if (filled_count != field.values.size()) {
        throw CliError(kExitFailure, "field stream: got " + std::to_string(filled_count) + " of " +
                                         std::to_string(field.values.size()) + " values");
      }
      return field;
    }
    if (status.error_code() == grpc::StatusCode::UNAVAILABLE && !have_header && attempt < 4) {
      std::this_thread::sleep_for(std::chrono::milliseconds(200 * attempt));
      continue;
    }
    throw status_error(status, conn.target());
  }
}

// --slice: "z=V" (x=, y= likewise: the plane through V on that axis, normal along it), or
// "PX,PY,PZ:NX,NY,NZ" (a point and a normal), in metres.
v1::Slice parse_slice(const std::string& text) {
  v1::Slice s;
  auto number = [&](const std::string& t) {
    char* end = nullptr;
    const double v = std::strtod(t.c_str(), &end);
    if (t.empty() || end != t.c_str() + t.size() || !std::isfinite(v)) {
      usage_error("--slice: '" + t + "' is not a number (expects z=V or PX,PY,PZ:NX,NY,NZ in m)");
    }
    return v;
  };
  if (text.size() > 2 && text[1] == '=' && (text[0] == 'x' || text[0] == 'y' || text[0] == 'z')) {
    const double v = number(text.substr(2));
    if (text[0] == 'x') s.set_px(v), s.set_nx(1);
    if (text[0] == 'y') s.set_py(v), s.set_ny(1);
    if (text[0] == 'z') s.set_pz(v), s.set_nz(1);
    return s;
  }
  const auto colon = text.find(':');
  std::vector<double> values;
  for (const std::string& part :
       {text.substr(0, colon),
        colon == std::string::npos ? std::string() : text.substr(colon + 1)}) {
    std::size_t start = 0;
    while (start <= part.size() && !part.empty()) {
      const std::size_t comma = part.find(',', start);
      values.push_back(number(part.substr(start, comma - start)));
      if (comma == std::string::npos) break;
      start = comma + 1;
    }
  }
  if (colon == std::string::npos || values.size() != 6) {
    usage_error("--slice: expects z=V (or x=, y=) or PX,PY,PZ:NX,NY,NZ, got '" + text + "'");
  }
  s.set_px(values[0]), s.set_py(values[1]), s.set_pz(values[2]);
  s.set_nx(values[3]), s.set_ny(values[4]), s.set_nz(values[5]);
  return s;
}

void write_field_csv(const std::string& path, const FieldData& f) {
  std::ofstream file;
  std::ostream* out = &std::cout;
  if (path != "-") {
    file.open(path);
    if (!file) throw CliError(kExitUsage, path + ": " + std::strerror(errno));
    out = &file;
  }
  const auto& h = f.header;
  const int comps = std::max(1, h.components());
  // value, or value_x,value_y[,value_z]
  std::string value_columns = comps == 1 ? "value" : "value_x,value_y";
  if (comps == 3) value_columns += ",value_z";
  const bool slice = h.slice_origin_size() == 3;
  if (h.location() == "raster") {
    // Cell centres in metres, so the file stands alone (no mesh needed to place the values); a
    // 3-D slice's cells also in the body's coordinates.
    *out << (slice ? "u,v,x,y,z," : "x,y,") << value_columns << '\n';
    const double dx = (h.x_max() - h.x_min()) / std::max(1, h.nx());
    const double dy = (h.y_max() - h.y_min()) / std::max(1, h.ny());
    for (int j = 0; j < h.ny(); ++j) {
      for (int i = 0; i < h.nx(); ++i) {
        std::size_t cell = static_cast<std::size_t>(j) * h.nx() + i;
        const double u = h.x_min() + (i + 0.5) * dx, v = h.y_min() + (j + 0.5) * dy;
        *out << fmt_exact(u) << ',' << fmt_exact(v);
        if (slice)
          for (int k = 0; k < 3; ++k)
            *out << ',' << fmt_exact(h.slice_origin(k) + u * h.slice_u(k) + v * h.slice_v(k));
        for (int c = 0; c < comps; ++c) *out << ',' << fmt_exact(f.values[cell * comps + c]);
        *out << '\n';
      }
    }
  } else if (h.location() == "surface") {
    // Node fields at the (clustered) vertices; element fields at the triangles' centroids.
    const auto nv = static_cast<std::size_t>(h.surface_vertices()),
               nt = static_cast<std::size_t>(h.surface_triangles());
    const double* xyz = f.values.data();
    const double* tri = xyz + 3 * nv;
    const double* val = tri + 3 * nt;
    const bool per_vertex = f.values.size() == 3 * nv + 3 * nt + nv * comps;
    *out << "x,y,z," << value_columns << '\n';
    for (std::size_t k = 0; k < (per_vertex ? nv : nt); ++k) {
      double p[3] = {0, 0, 0};
      for (int d = 0; d < 3; ++d) {
        if (per_vertex) {
          p[d] = xyz[3 * k + d];
        } else {
          for (int c = 0; c < 3; ++c)
            p[d] += xyz[3 * static_cast<std::size_t>(tri[3 * k + c]) + d] / 3.0;
        }
      }
      *out << fmt_exact(p[0]) << ',' << fmt_exact(p[1]) << ',' << fmt_exact(p[2]);
      for (int c = 0; c < comps; ++c) *out << ',' << fmt_exact(val[k * comps + c]);
      *out << '\n';
    }
  } else {
    // Index into the full node or element array (the sample k is index k * every).
    *out << "index," << value_columns << '\n';
    const std::size_t every = static_cast<std::size_t>(std::max(1, h.every()));
    for (std::size_t k = 0; k * comps < f.values.size(); ++k) {
      *out << k * every;
      for (int c = 0; c < comps; ++c) *out << ',' << fmt_exact(f.values[k * comps + c]);
      *out << '\n';
    }
  }
  out->flush();
  if (!*out) throw CliError(kExitFailure, path + ": write failed");
}

void print_field_summary(const FieldData& f, const std::vector<std::string>& written) {
  const auto& h = f.header;
  std::size_t nan = 0, n = 0;
  double lo = INFINITY, hi = -INFINITY, sum = 0;
  const int comps = std::max(1, h.components());
  // Statistics of the magnitude for vectors: a single min/max of interleaved x, y means little.
  const std::size_t first =
      h.location() == "surface"
          ? 3 * static_cast<std::size_t>(h.surface_vertices() + h.surface_triangles())
          : 0;
  for (std::size_t k = 0; first + k * comps < f.values.size(); ++k) {
    const double* item = f.values.data() + first + k * comps;
    double v = 0;
    if (comps == 1) {
      v = item[0];
    } else {
      for (int c = 0; c < comps; ++c) v += item[c] * item[c];
      v = std::sqrt(v);
    }
    if (std::isnan(v)) {
      ++nan;
      continue;
    }
    ++n;
    lo = std::min(lo, v);
    hi = std::max(hi, v);
    sum += v;
  }
  KeyValues kv;
  kv.add("field", h.name() + (h.units().empty() ? "" : " (" + h.units() + ")"));
  kv.add("frame", std::to_string(h.frame()));
  kv.add("time", fmt_ns(h.time()));
  kv.add("location", h.location());
  kv.add("components", std::to_string(comps));
  if (h.location() == "raster" && h.slice_origin_size() == 3) {
    auto vec = [&](auto get) {
      return "(" + fmt_num(get(0)) + ", " + fmt_num(get(1)) + ", " + fmt_num(get(2)) + ")";
    };
    kv.add("slice", "through " + vec([&](int k) { return h.slice_origin(k) * 1e6; }) +
                        " µm, axes u " + vec([&](int k) { return h.slice_u(k); }) + ", v " +
                        vec([&](int k) { return h.slice_v(k); }));
  }
  if (h.location() == "surface") {
    kv.add("surface", std::to_string(h.surface_vertices()) + " vertices, " +
                          std::to_string(h.surface_triangles()) + " triangles");
  }
  if (h.location() == "raster") {
    kv.add("raster", std::to_string(h.nx()) + " x " + std::to_string(h.ny()));
    kv.add("extent", "x " + fmt_num(h.x_min() * 1e6) + " .. " + fmt_num(h.x_max() * 1e6) +
                         " µm, y " + fmt_num(h.y_min() * 1e6) + " .. " + fmt_num(h.y_max() * 1e6) +
                         " µm");
  } else if (h.location() != "surface") {
    kv.add("every", std::to_string(std::max(1, h.every())));
  }
  // The field's own values (a surface's stream begins with its geometry).
  const std::size_t geometry =
      h.location() == "surface"
          ? 3 * static_cast<std::size_t>(h.surface_vertices() + h.surface_triangles())
          : 0;
  kv.add("values", std::to_string((f.values.size() - geometry) / comps) +
                       (nan ? " (" + std::to_string(nan) + " outside the body)" : ""));
  std::string what = comps == 1 ? "" : " |v|";
  if (n > 0) {
    kv.add("min" + what, fmt_num(lo));
    kv.add("max" + what, fmt_num(hi));
    kv.add("mean" + what, fmt_num(sum / n));
  }
  for (const auto& w : written) kv.add("wrote", w);
  kv.print(stdout);
}

}  // namespace

int cmd_field(const GlobalOptions& g, const ParsedArgs& a) {
  v1::GetFieldRequest request;
  request.set_id(a.positional.at(0));
  auto name = a.get("name");
  if (!name || name->empty())
    usage_error(
        "--name is required (J, mean_stress, hoop_stress, "
        "radial_stress, von_mises, displacement, velocity, damage)");
  request.set_name(*name);
  if (a.has("time") && a.has("frame")) usage_error("give --time or --frame, not both");
  if (auto t = a.get("time")) request.set_time(parse_time_seconds("time", *t));
  if (auto k = a.get("frame")) request.set_frame(parse_nonneg_int32("frame", *k));
  if (a.has("raster") + a.has("every") + a.has("surface") > 1)
    usage_error("give one of --raster, --every and --surface");
  if (auto r = a.get("raster")) {
    auto [nx, ny] = parse_raster("raster", *r);
    request.mutable_raster()->set_nx(nx);
    request.mutable_raster()->set_ny(ny);
  }
  if (a.has("every")) request.set_every(parse_every(a));
  if (auto sl = a.get("slice")) {
    *request.mutable_slice() = parse_slice(*sl);
    if (!request.has_raster() && !a.has("every") && !a.has("surface")) {
      request.mutable_raster()->set_nx(256);  // a slice is a raster
      request.mutable_raster()->set_ny(256);
    }
  }
  if (auto n = a.get("surface")) {
    request.mutable_surface()->set_max_triangles(parse_nonneg_int32("surface", *n));
  }
  auto png = a.get("png");
  auto csv = a.get("csv");
  if (png) {
    if (a.has("every") || a.has("surface"))
      usage_error("--png needs a raster (--raster NXxNY or --slice), not --every or --surface");
    // A picture needs values on a grid; 256 x 256 resolves the baseline disk's elements.
    if (!request.has_raster()) {
      request.mutable_raster()->set_nx(256);
      request.mutable_raster()->set_ny(256);
    }
  }

  Connection conn(g);
  FieldData field = fetch_field(conn, request);
  const auto& h = field.header;
  std::vector<std::string> written;
  if (csv) {
    write_field_csv(*csv, field);
    if (*csv != "-") written.push_back(*csv);
  }
  if (png) {
    if (h.location() != "raster" || h.nx() < 1 || h.ny() < 1) {
      throw CliError(kExitFailure, "server did not return a raster for the PNG");
    }
    TempDir tmp;
    const std::string npy = tmp.path() + "/field.npy";
    std::vector<std::size_t> shape = {static_cast<std::size_t>(h.ny()),
                                      static_cast<std::size_t>(h.nx())};
    if (h.components() > 1) shape.push_back(static_cast<std::size_t>(h.components()));
    write_npy(npy, field.values, shape);
    // "--opt=value" throughout: a negative number as a separate word would look like an option
    // to argparse, and so would a name or path starting with '-'.
    run_python_plot({"field-raster", "--npy=" + npy, "--x-min=" + fmt_exact(h.x_min()),
                     "--x-max=" + fmt_exact(h.x_max()), "--y-min=" + fmt_exact(h.y_min()),
                     "--y-max=" + fmt_exact(h.y_max()), "--name=" + h.name(),
                     "--units=" + h.units(), "--time=" + fmt_exact(h.time()),
                     "--frame=" + std::to_string(h.frame()), "--out=" + *png});
    written.push_back(*png);
  }
  if (csv && *csv == "-") return kExitOk;  // stdout carries the CSV: nothing else may go there
  if (g.json) {
    v1::FieldChunk whole;
    *whole.mutable_header() = h;
    if (!csv && !png) {
      whole.mutable_values()->Assign(field.values.begin(), field.values.end());
    }
    std::printf("%s\n", to_json(whole).c_str());
  } else {
    print_field_summary(field, written);
  }
  return kExitOk;
}

}  // namespace softshock::cli
