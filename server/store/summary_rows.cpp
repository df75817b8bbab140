#include "server/store/summary_rows.hpp"

#include <array>
#include <cmath>
#include <cstdint>
#include <type_traits>
#include <vector>

#include "solver/summary_figures.hpp"

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

// count: an integer of any width, stored as INTEGER.
template <typename Record, auto... Path>
constexpr Column<Record> count(const char* name) {
  return {name,
          [](Stmt& s, int i, const Record& r) {
            s.bind(i, static_cast<int64_t>(member_at<Path...>(r)));
          },
          [](const Stmt& s, int c, Record& r) {
            auto& f = member_at<Path...>(r);
            f = static_cast<std::remove_reference_t<decltype(f)>>(s.i64(c));
          }};
}
// series: a vector of doubles as a BLOB.
template <typename Record, auto... Path>
constexpr Column<Record> series(const char* name) {
  return {name, [](Stmt& s, int i, const Record& r) { s.bind_blob(i, member_at<Path...>(r)); },
          [](const Stmt& s, int c, Record& r) { member_at<Path...>(r) = s.doubles(c); }};
}

using SS = StoredSummary;

// The run's figures: job_summaries' columns, the catalogued rows of summary_figures().
const std::vector<const SummaryFigure*>& catalogued_figures() {
  static const std::vector<const SummaryFigure*> figures = [] {
    std::vector<const SummaryFigure*> out;
    for (const auto& f : summary_figures()) {
      if (f.column) out.push_back(&f);
    }
    return out;
  }();
  return figures;
}

void bind_figure(Stmt& s, int i, const SummaryFigure& f, const RunSummary& r) {
  switch (f.type) {
    case FigureType::kText:
      s.bind(i, f.text(r));
      break;
    case FigureType::kSeries:
      s.bind_blob(i, f.series(r));
      break;
    case FigureType::kInteger:
    case FigureType::kFlag:
      s.bind(i, static_cast<int64_t>(f.get(r)));
      break;
    case FigureType::kReal:
      bind_figure(s, i, f.get(r));
      break;
  }
}

void read_figure(const Stmt& s, int c, const SummaryFigure& f, RunSummary& r) {
  switch (f.type) {
    case FigureType::kText:
      f.text_ref(r) = s.text(c);
      break;
    case FigureType::kSeries:
      f.series_ref(r) = s.doubles(c);
      break;
    case FigureType::kInteger:
    case FigureType::kFlag:
      f.set(r, static_cast<double>(s.i64(c)));
      break;
    case FigureType::kReal:
      f.set(r, read_figure(s, c));
      break;
  }
}

// The decimated series a StoredSummary adds: heavy, so read only where they are needed.
const std::array<Column<SS>, 5> kSeries = {{
    count<SS, &SS::mode_count>("mode_count"),
    series<SS, &SS::mode_times>("mode_times"),
    series<SS, &SS::mode_amplitudes>("mode_amplitudes"),
    series<SS, &SS::abar_times>("abar_times"),
    series<SS, &SS::abar_values>("abar_values"),
}};

const char* column_name(const SummaryFigure* f) {
  return f->column;
}
template <typename Record>
const char* column_name(const Column<Record>& c) {
  return c.name;
}

template <typename Columns>
void append_names(std::string& out, const Columns& columns, const std::string& t) {
  for (const auto& column : columns) out += (out.empty() ? "" : ", ") + t + column_name(column);
}

}  // namespace

std::string summary_columns(const std::string& t) {
  std::string out;
  append_names(out, catalogued_figures(), t);
  return out;
}

int summary_column_count() {
  return static_cast<int>(catalogued_figures().size());
}

RunSummary read_summary(const Stmt& s, int c) {
  RunSummary r;
  for (const SummaryFigure* f : catalogued_figures()) read_figure(s, c++, *f, r);
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
    for (std::size_t k = 0; k < catalogued_figures().size() + kSeries.size(); ++k) values += ", ?";
    return "INSERT OR REPLACE INTO job_summaries(job_id, " + stored_summary_columns() +
           ") VALUES (" + values + ")";
  }();
  auto s = c.prepare(sql);
  int i = 1;
  s.bind(i++, id);
  for (const SummaryFigure* f : catalogued_figures()) bind_figure(s, i++, *f, stored.summary);
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
    // The query figures as numbers: the 'NaN' text of bind_figure() becomes NULL (not known)
    // in the nullable jobs columns, so it never compares as text in a filter.
    for (const auto& figure : summary_figures()) {
      if (!figure.has(kQueryable)) continue;
      const std::string f = figure.column;
      names += (names.empty() ? "" : ", ") + f;
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
