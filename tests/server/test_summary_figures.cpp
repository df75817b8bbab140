// The one table of a run's summary figures (solver/summary_figures.hpp) against everything that
// reads it: the summary JSON, the JobSummary message, the catalogue's columns and grid
// reductions. A figure added to RunSummary and JobSummary but not to the table, or a catalogue
// column without a figure, fails here.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <random>
#include <set>
#include <string>

#include "server/jobs/grid.hpp"
#include "server/jobs/job_runner.hpp"
#include "server/store/catalogue.hpp"
#include "server/store/sqlite_connection.hpp"
#include "server/transport/rpc_support.hpp"
#include "solver/summary_figures.hpp"

namespace softshock::server {
namespace {

namespace fs = std::filesystem;
using google::protobuf::FieldDescriptor;

// A 3-D run with damage whose every figure holds a value of its own: the k-th figure k + 0.5
// (integers k), texts "text-k", series {k + 1/4, k + 3/4} (short decimals: the JSON's 10
// significant digits carry them exactly).
RunSummary distinct_summary() {
  RunSummary s;
  int k = 0;
  for (const auto& f : summary_figures()) {
    ++k;
    if (f.has(kDerived)) continue;
    switch (f.type) {
      case FigureType::kText:
        f.text_ref(s) = "text-" + std::to_string(k);
        break;
      case FigureType::kSeries:
        f.series_ref(s) = {k + 0.25, k + 0.75};
        break;
      case FigureType::kInteger:
        f.set(s, k);
        break;
      case FigureType::kFlag:
        break;
      case FigureType::kReal:
        f.set(s, k + 0.5);
        break;
    }
  }
  s.damage = true;
  s.dimension = 3;
  return s;
}

void expect_same_figure(const SummaryFigure& f, const RunSummary& a, const RunSummary& b) {
  SCOPED_TRACE(f.name);
  switch (f.type) {
    case FigureType::kText:
      EXPECT_EQ(f.text(a), f.text(b));
      break;
    case FigureType::kSeries:
      EXPECT_EQ(f.series(a), f.series(b));
      break;
    default:
      EXPECT_EQ(f.get(a), f.get(b));
  }
}

TEST(SummaryFigures, EveryFigureSurvivesTheSummaryJson) {
  const RunSummary in = distinct_summary();
  const std::string json = summary_to_json(in);
  const RunSummary out = parse_summary_json(json);
  for (const auto& f : summary_figures()) {
    if (f.has(kNotInJson)) continue;
    EXPECT_NE(json.find(std::string("\"") + f.name + "\":"), std::string::npos) << f.name;
    if (!f.has(kDerived)) expect_same_figure(f, in, out);
  }
  EXPECT_TRUE(out.damage);
  // The conditional ones are left out where the run has none.
  RunSummary plain = in;
  plain.damage = false, plain.dimension = 2, plain.error.clear();
  const std::string json2 = summary_to_json(plain);
  for (const char* absent : {"damage_onset_s", "thickness_m", "dimension", "error", "damage"}) {
    EXPECT_EQ(json2.find(std::string("\"") + absent + "\":"), std::string::npos) << absent;
  }
  const RunSummary out2 = parse_summary_json(json2);
  EXPECT_FALSE(out2.damage);
  EXPECT_EQ(out2.dimension, 2);
}

// JobSummary's fields are the table's figures by name, both ways, and fill_summary() sets each
// to the figure's value.
TEST(SummaryFigures, JobSummaryHasAFieldForEveryFigureAndNoOther) {
  auto check_message = [](const google::protobuf::Descriptor* d, bool groups) {
    for (int i = 0; i < d->field_count(); ++i) {
      const std::string name = d->field(i)->name();
      if (!groups && (name == "id" || name == "groups")) continue;
      const SummaryFigure* f = find_summary_figure(name);
      ASSERT_NE(f, nullptr) << d->name() << "." << name << " is not in summary_figures()";
      EXPECT_EQ(name, f->name) << "a former name";
      EXPECT_FALSE(f->has(kNotInJobSummary)) << name;
      EXPECT_EQ(f->has(kInGroups), groups) << name;
      EXPECT_EQ(d->field(i)->is_repeated(), f->type == FigureType::kSeries) << name;
      EXPECT_EQ(d->field(i)->cpp_type() == FieldDescriptor::CPPTYPE_STRING,
                f->type == FigureType::kText)
          << name;
    }
  };
  check_message(v1::JobSummary::descriptor(), false);
  check_message(v1::NondimensionalGroups::descriptor(), true);
  for (const auto& f : summary_figures()) {
    if (f.has(kNotInJobSummary)) continue;
    const auto* d =
        f.has(kInGroups) ? v1::NondimensionalGroups::descriptor() : v1::JobSummary::descriptor();
    EXPECT_NE(d->FindFieldByName(f.name), nullptr) << f.name << " has no field in " << d->name();
  }

  const RunSummary s = distinct_summary();
  v1::JobSummary m;
  rpc::fill_summary("id-1", s, &m);
  EXPECT_EQ(m.id(), "id-1");
  for (const auto& f : summary_figures()) {
    if (f.has(kNotInJobSummary)) continue;
    SCOPED_TRACE(f.name);
    const google::protobuf::Message& msg =
        f.has(kInGroups) ? static_cast<const google::protobuf::Message&>(m.groups()) : m;
    const auto* field = msg.GetDescriptor()->FindFieldByName(f.name);
    const auto* r = msg.GetReflection();
    if (f.type == FigureType::kSeries) {
      ASSERT_EQ(r->FieldSize(msg, field), 2);
      EXPECT_EQ(r->GetRepeatedDouble(msg, field, 1), f.series(s)[1]);
      continue;
    }
    switch (field->cpp_type()) {
      case FieldDescriptor::CPPTYPE_DOUBLE:
        EXPECT_EQ(r->GetDouble(msg, field), f.get(s));
        break;
      case FieldDescriptor::CPPTYPE_INT64:
        EXPECT_EQ(r->GetInt64(msg, field), static_cast<int64_t>(f.get(s)));
        break;
      case FieldDescriptor::CPPTYPE_INT32:
        EXPECT_EQ(r->GetInt32(msg, field), static_cast<int32_t>(f.get(s)));
        break;
      case FieldDescriptor::CPPTYPE_BOOL:
        EXPECT_EQ(r->GetBool(msg, field), f.get(s) != 0);
        break;
      case FieldDescriptor::CPPTYPE_STRING:
        EXPECT_EQ(r->GetString(msg, field), f.text(s));
        break;
      default:
        ADD_FAILURE() << "unexpected type";
    }
  }
}

class SummaryFiguresCatalogue : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ =
        fs::temp_directory_path() / ("softshock-figures-" + std::to_string(std::random_device{}()));
    fs::create_directories(dir_);
    path_ = (dir_ / "catalogue.sqlite").string();
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::set<std::string> columns(const std::string& table) {
    detail::SqliteConnection c(path_);
    auto s = c.prepare("SELECT name FROM pragma_table_info('" + table + "')");
    std::set<std::string> out;
    while (s.step()) out.insert(s.text(0));
    return out;
  }

  fs::path dir_;
  std::string path_;
};

// After every migration, job_summaries has a column for each catalogued figure and none
// besides (but the job's id and the decimated series), the jobs table one for each query
// figure; and every catalogued figure comes back as it went in.
TEST_F(SummaryFiguresCatalogue, EveryCataloguedFigureHasItsColumnAndRoundTrips) {
  { Catalogue c(path_); }
  std::set<std::string> summaries = columns("job_summaries");
  const std::set<std::string> jobs = columns("jobs");
  for (const auto& f : summary_figures()) {
    if (!f.column) {
      EXPECT_TRUE(f.has(kDerived) || f.has(kNotInJobSummary)) << f.name << " is not catalogued";
      continue;
    }
    EXPECT_EQ(summaries.erase(f.column), 1u) << "no job_summaries column for " << f.name;
    if (f.has(kQueryable)) {
      EXPECT_TRUE(jobs.contains(f.column)) << "no jobs column " << f.column;
    }
  }
  EXPECT_EQ(summaries, (std::set<std::string>{"job_id", "mode_count", "mode_times",
                                              "mode_amplitudes", "abar_times", "abar_values"}))
      << "job_summaries columns that no figure fills";

  Catalogue c(path_);
  NewJob j;
  j.id = "a";
  j.spec_json = "{}";
  j.spec_hash = "h";
  j.create_us = now_us();
  ASSERT_TRUE(c.insert(j).created);
  ASSERT_TRUE(c.start("a", now_us()));
  StoredSummary in;
  in.summary = distinct_summary();
  ASSERT_TRUE(c.finish("a", 1, JobState::kSucceeded, "", "", "/r/result.h5", {}, &in, now_us()));
  const auto out = c.summary("a");
  ASSERT_TRUE(out);
  for (const auto& f : summary_figures()) {
    if (f.column) expect_same_figure(f, in.summary, out->summary);
  }
  // The jobs row's query figures are the summary's.
  JobQuery q;
  for (const auto& f : summary_figures()) {
    if (!f.has(kQueryable)) continue;
    RangeCondition at;
    at.name = f.name;
    at.ge = at.le = f.get(in.summary);
    q.conditions = {at};
    EXPECT_EQ(c.query(q).size(), 1u) << f.name;
  }
}

TEST(SummaryFigures, GridQuantitiesAreTheTablesGridFigures) {
  EXPECT_STREQ(grid_quantities().front().name, "max_abar_first_cycle");
  std::set<std::string> from_table;
  for (const auto& f : summary_figures()) {
    if (f.has(kGridQuantity)) from_table.insert(f.name);
  }
  std::set<std::string> quantities;
  StoredSummary stored;
  stored.summary = distinct_summary();
  for (const auto& q : grid_quantities()) {
    if (q.needs_tbar) continue;
    quantities.insert(q.name);
    ASSERT_NE(q.figure, nullptr) << q.name;
    EXPECT_STREQ(q.units, q.figure->unit);
    EXPECT_EQ(grid_quantity(q, stored, 0), q.figure->get(stored.summary)) << q.name;
  }
  EXPECT_EQ(quantities, from_table);
  // A run without damage has no damage figures, a shock never detected no arrival time.
  stored.summary.damage = false;
  stored.summary.shock_at_center_s = -1;
  EXPECT_TRUE(std::isnan(grid_quantity(*find_grid_quantity("damage_onset_s"), stored, 0)));
  EXPECT_TRUE(std::isnan(grid_quantity(*find_grid_quantity("max_damaged_volume"), stored, 0)));
  EXPECT_TRUE(std::isnan(grid_quantity(*find_grid_quantity("shock_at_center_s"), stored, 0)));
}

TEST(SummaryFigures, FormerNamesFindTodaysFigure) {
  EXPECT_EQ(current_summary_name("energy_injected"), "energy_injected_J_per_m");
  EXPECT_EQ(current_summary_name("grind_time"), "grind_ns");
  EXPECT_EQ(current_summary_name("time_scale"), "time_scale_s");
  EXPECT_EQ(current_summary_name("pbar"), "pbar");
  EXPECT_EQ(current_summary_name("no_such_figure"), "no_such_figure");
  EXPECT_EQ(renamed_summary_names().size(), 16u);  // the rename of 2026-12-05 (docs/api.md)
  std::set<std::string> names;
  for (const auto& f : summary_figures()) {
    EXPECT_TRUE(names.insert(f.name).second) << "two figures named " << f.name;
    if (f.former) {
      EXPECT_TRUE(names.insert(f.former).second) << f.former;
    }
  }
}

}  // namespace
}  // namespace softshock::server
