// The one table of a run's summary figures (RunSummary): for each, the name clients see, its
// unit and meaning, and where it goes. The summary JSON (summary_to_json, the daemon's parser),
// the catalogue (job_summaries' columns, the jobs table's query columns), transport (JobSummary,
// filled by name) and grid reductions all read this table, so a new figure is a RunSummary
// member, a row here, a JobSummary field of the same name and a catalogue migration
// (tests/server/test_summary_figures.cpp checks the last two against the table).
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "run_summary.hpp"

namespace softshock {

// The member a path of member pointers leads to: member_at<&A::b, &B::c>(a) is a.b.c.
template <auto First, auto... Rest>
constexpr auto& member_at(auto& record) {
  if constexpr (sizeof...(Rest) == 0) {
    return record.*First;
  } else {
    return member_at<Rest...>(record.*First);
  }
}

enum class FigureType { kInteger, kReal, kFlag, kText, kSeries };

// Where a figure goes and how it reads (bits of SummaryFigure::traits).
enum FigureTrait : unsigned {
  kInGroups = 1u << 0,          // inside "groups" (JSON) / JobSummary.groups
  kDerived = 1u << 1,           // computed from other figures: written, never read or catalogued
  kOptional = 1u << 2,          // absent from older results: reads as RunSummary's default
  kOnly3D = 1u << 3,            // written only for a run with tetrahedra
  kOnlyDamage = 1u << 4,        // written only for a run with phase-field damage
  kOnlyNonEmpty = 1u << 5,      // text written only when not empty
  kNotInJson = 1u << 6,         // not a key of its own (damage: the damage figures' presence)
  kQueryable = 1u << 7,         // a QueryJobs name: a column of the jobs table as well
  kGridQuantity = 1u << 8,      // a grid reduction's quantity
  kNegativeIsNone = 1u << 9,    // negative means "never" / "not detected": NaN in reductions
  kNotInJobSummary = 1u << 10,  // the job reports it (its state and error), not JobSummary
};

struct SummaryFigure {
  const char* name;     // JSON key, JobSummary field, query and grid name (unit in the name)
  const char* former;   // its name before the units were added to names; nullptr if none
  const char* column;   // job_summaries' column; nullptr: not catalogued
  const char* unit;     // "1" for a pure number, "" for text
  const char* meaning;  // one line, for help texts and docs
  FigureType type;
  unsigned traits;
  // kInteger, kReal, kFlag: the value as a double (integers are exact below 2^53); set is null
  // for a derived figure.
  double (*get)(const RunSummary&) = nullptr;
  void (*set)(RunSummary&, double) = nullptr;
  // kText and kSeries.
  const std::string& (*text)(const RunSummary&) = nullptr;
  std::string& (*text_ref)(RunSummary&) = nullptr;
  const std::vector<double>& (*series)(const RunSummary&) = nullptr;
  std::vector<double>& (*series_ref)(RunSummary&) = nullptr;

  bool has(unsigned trait) const { return (traits & trait) != 0; }
  // Whether summary_to_json writes it for this run.
  bool written_for(const RunSummary& s) const;
};

// Every figure, in the summary JSON's order.
std::span<const SummaryFigure> summary_figures();
// The figure of that name (today's or its former one), or nullptr.
const SummaryFigure* find_summary_figure(std::string_view name);

// A numeric figure as a reduction or a query reads it: NaN where the run has no such value (a
// damage figure without damage, a negative "never" of a kNegativeIsNone figure).
double figure_value(const SummaryFigure& figure, const RunSummary& s);

}  // namespace softshock
