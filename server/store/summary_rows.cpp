#include "server/store/summary_rows.hpp"

#include <array>
#include <cmath>
#include <cstdint>
#include <type_traits>

namespace softshock::server::detail {
namespace {

using Stmt = SqliteConnection::Stmt;

// A summary figure. NaN cannot be stored in the NOT NULL REAL columns of job_summaries (SQLite
// binds NaN as NULL), so it is stored as the text 'NaN', which REAL affinity leaves as text;
// any text reads back as NaN. +-Inf are ordinary REAL values.
void bind_figure(Stmt& s, int i, double v) {
  if (std::isnan(v)) {
    s.bind(i, std::string("NaN"));
  } else {
    s.bind(i, v);
  }
}
double read_figure(const Stmt& s, int col) {
  return s.is_text(col) || s.is_null(col) ? NAN : s.dbl(col);
}

// One column of job_summaries: its name, how a record's field is bound into it and read back.
template <typename Record>
struct Column {
  const char* name;
  void (*bind)(Stmt& s, int index, const Record& r);
  void (*read)(const Stmt& s, int col, Record& r);
};

// The field a path of member pointers leads to: field<&A::b, &B::c>(a) is a.b.c.
template <auto First, auto... Rest>
constexpr auto& field(auto& record) {
  if constexpr (sizeof...(Rest) == 0) {
    return record.*First;
  } else {
    return field<Rest...>(record.*First);
  }
}

// The kinds of column. figure: a double whose NaN survives (bind_figure / read_figure).
template <typename Record, auto... Path>
constexpr Column<Record> figure(const char* name) {
  return {name, [](Stmt& s, int i, const Record& r) { bind_figure(s, i, field<Path...>(r)); },
          [](const Stmt& s, int c, Record& r) { field<Path...>(r) = read_figure(s, c); }};
}
// count: an integer of any width, stored as INTEGER.
template <typename Record, auto... Path>
constexpr Column<Record> count(const char* name) {
  return {
      name,
      [](Stmt& s, int i, const Record& r) { s.bind(i, static_cast<int64_t>(field<Path...>(r))); },
      [](const Stmt& s, int c, Record& r) {
        auto& f = field<Path...>(r);
        f = static_cast<std::remove_reference_t<decltype(f)>>(s.i64(c));
      }};
}
template <typename Record, auto... Path>
constexpr Column<Record> text(const char* name) {
  return {name, [](Stmt& s, int i, const Record& r) { s.bind(i, field<Path...>(r)); },
          [](const Stmt& s, int c, Record& r) { field<Path...>(r) = s.text(c); }};
}
// series: a vector of doubles as a BLOB.
template <typename Record, auto... Path>
constexpr Column<Record> series(const char* name) {
  return {name, [](Stmt& s, int i, const Record& r) { s.bind_blob(i, field<Path...>(r)); },
          [](const Stmt& s, int c, Record& r) { field<Path...>(r) = s.doubles(c); }};
}

using RS = RunSummary;
using G = NondimensionalGroups;
using SS = StoredSummary;

// The run's figures: job_summaries' columns for RunSummary (every one of its fields but none
// of the decimated series).
const std::array<Column<RS>, 45> kFigures = {{
    count<RS, &RS::elements>("elements"),
    count<RS, &RS::nodes>("nodes"),
    count<RS, &RS::steps>("steps"),
    figure<RS, &RS::wall_time_s>("wall_time"),
    figure<RS, &RS::end_time_s>("end_time"),
    figure<RS, &RS::groups, &G::pbar>("pbar"),
    figure<RS, &RS::groups, &G::tbar_pulse>("tbar_pulse"),
    figure<RS, &RS::groups, &G::mubar>("mubar"),
    figure<RS, &RS::groups, &G::gamma>("gamma"),
    figure<RS, &RS::groups, &G::c1>("c1"),
    figure<RS, &RS::groups, &G::c2>("c2"),
    figure<RS, &RS::groups, &G::time_scale_s>("time_scale"),
    figure<RS, &RS::energy_injected_J_per_m>("energy_injected"),
    figure<RS, &RS::energy_after_pulse_J_per_m>("energy_after_pulse"),
    figure<RS, &RS::max_abar_first_cycle>("max_abar_first_cycle"),
    figure<RS, &RS::max_abar>("max_abar"),
    count<RS, &RS::dominant_mode_end>("dominant_mode_end"),
    figure<RS, &RS::shock_at_center_s>("shock_at_center"),
    series<RS, &RS::rim_reflections_s>("rim_reflections"),
    figure<RS, &RS::min_dt_s>("min_dt"),
    figure<RS, &RS::max_dt_s>("max_dt"),
    text<RS, &RS::status>("status"),
    text<RS, &RS::error>("error"),
    figure<RS, &RS::kernel_time_s>("kernel_time"),
    figure<RS, &RS::meshing_time_s>("meshing_time"),
    text<RS, &RS::mesh_cache>("mesh_cache"),
    figure<RS, &RS::max_abar_filtered_first_cycle>("max_abar_filtered_first_cycle"),
    figure<RS, &RS::max_abar_filtered>("max_abar_filtered"),
    figure<RS, &RS::abar_end>("abar_end"),
    figure<RS, &RS::abar_filtered_end>("abar_filtered_end"),
    figure<RS, &RS::max_aspect_ratio>("max_aspect_ratio"),
    figure<RS, &RS::aspect_ratio_above_10_s>("aspect_ratio_above_10"),
    count<RS, &RS::solver_revision>("solver_revision"),
    figure<RS, &RS::diagnostics_time_s>("diagnostics_time"),
    figure<RS, &RS::output_time_s>("output_time"),
    count<RS, &RS::damage>("damage"),
    figure<RS, &RS::damage_onset_s>("damage_onset"),
    figure<RS, &RS::max_damaged_volume>("max_damaged_volume"),
    figure<RS, &RS::max_damaged_radius_m>("max_damaged_radius"),
    figure<RS, &RS::damage_dissipation_J_per_m>("damage_dissipation"),
    figure<RS, &RS::crack_energy_J_per_m>("crack_energy"),
    figure<RS, &RS::damage_time_s>("damage_time"),
    count<RS, &RS::damage_solves>("damage_solves"),
    count<RS, &RS::dimension>("dimension"),
    figure<RS, &RS::thickness_m>("thickness"),
}};

// The decimated series a StoredSummary adds: heavy, so read only where they are needed.
const std::array<Column<SS>, 5> kSeries = {{
    count<SS, &SS::mode_count>("mode_count"),
    series<SS, &SS::mode_times>("mode_times"),
    series<SS, &SS::mode_amplitudes>("mode_amplitudes"),
    series<SS, &SS::abar_times>("abar_times"),
    series<SS, &SS::abar_values>("abar_values"),
}};

template <typename Columns>
void append_names(std::string& out, const Columns& columns, const std::string& t) {
  for (const auto& column : columns) out += (out.empty() ? "" : ", ") + t + column.name;
}

// The summary's query figures as numbers: the 'NaN' text of bind_figure() becomes NULL (not
// known) in the nullable jobs columns, so it never compares as text in a filter.
constexpr const char* kQueryFigures[] = {"pbar",
                                         "tbar_pulse",
                                         "mubar",
                                         "gamma",
                                         "c1",
                                         "c2",
                                         "max_abar_first_cycle",
                                         "max_abar",
                                         "energy_injected",
                                         "energy_after_pulse",
                                         "dominant_mode_end",
                                         "shock_at_center",
                                         "wall_time",
                                         "elements",
                                         "steps"};

}  // namespace

std::string summary_columns(const std::string& t) {
  std::string out;
  append_names(out, kFigures, t);
  return out;
}

int summary_column_count() {
  return static_cast<int>(kFigures.size());
}

RunSummary read_summary(const Stmt& s, int c) {
  RunSummary r;
  for (const auto& column : kFigures) column.read(s, c++, r);
  return r;
}

std::string stored_summary_columns() {
  std::string out = summary_columns();
  append_names(out, kSeries, "");
  return out;
}

StoredSummary read_stored_summary(const Stmt& s, int c) {
  StoredSummary out;
  out.summary = read_summary(s, c);
  c += summary_column_count();
  for (const auto& column : kSeries) column.read(s, c++, out);
  return out;
}

void write_summary(SqliteConnection& c, const std::string& id, const StoredSummary& stored) {
  static const std::string sql = [] {
    std::string values = "?";
    for (std::size_t k = 0; k < kFigures.size() + kSeries.size(); ++k) values += ", ?";
    return "INSERT OR REPLACE INTO job_summaries(job_id, " + stored_summary_columns() +
           ") VALUES (" + values + ")";
  }();
  auto s = c.prepare(sql);
  int i = 1;
  s.bind(i++, id);
  for (const auto& column : kFigures) column.bind(s, i++, stored.summary);
  for (const auto& column : kSeries) column.bind(s, i++, stored);
  s.run();
}

void copy_summary(SqliteConnection& c, const std::string& id, const std::string& source) {
  static const std::string sql = "INSERT OR REPLACE INTO job_summaries(job_id, " +
                                 stored_summary_columns() + ") SELECT ?, " +
                                 stored_summary_columns() + " FROM job_summaries WHERE job_id = ?";
  auto s = c.prepare(sql);
  s.bind(1, id).bind(2, source);
  s.run();
}

void refresh_query_columns(SqliteConnection& c, const std::string& id) {
  static const std::string sql = [] {
    std::string names, figures;
    for (const char* f : kQueryFigures) {
      names += (names.empty() ? "" : ", ") + std::string(f);
      figures += (figures.empty() ? "" : ", ") + std::string("CASE WHEN typeof(") + f +
                 ") IN ('real', 'integer') THEN " + f + " END";
    }
    return "UPDATE jobs SET (" + names + ") = (SELECT " + figures +
           " FROM job_summaries WHERE job_id = ?1) WHERE id = ?1 AND "
           "EXISTS (SELECT 1 FROM job_summaries WHERE job_id = ?1)";
  }();
  auto s = c.prepare(sql);
  s.bind(1, id);
  s.run();
}

}  // namespace softshock::server::detail
