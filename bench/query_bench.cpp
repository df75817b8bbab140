// Cost of result-database queries (QueryJobs' SQL and the grid reduction's read) on a catalogue
// of 10,000 finished jobs filled synthetically: 83 grids of 121 points, groups and summary
// figures drawn at random, A-bar samples and decimated mode amplitudes the size of a 254 ns
// run's (so summary rows are as large as real ones). Only the catalogue is timed (the
// gRPC answer adds the Job messages). Figures: docs/performance.md.
//
//   build/bench/query_bench [--jobs=N] [benchmark flags]   (catalogue in $TMPDIR or /dev/shm)
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <filesystem>
#include <memory>
#include <random>
#include <string>

#include "server/store/catalogue.hpp"

namespace softshock::server {
namespace {

namespace fs = std::filesystem;

int g_jobs = 10000;

// The catalogue, filled once for every benchmark. On /dev/shm when there is one: the fill
// commits 10,000 fsynced transitions, which says nothing about query cost.
class Fixture {
 public:
  Fixture() {
    const fs::path base = fs::exists("/dev/shm") ? fs::path("/dev/shm") : fs::temp_directory_path();
    dir_ = base / ("softshock-query-bench-" + std::to_string(std::random_device{}()));
    fs::create_directories(dir_);
    catalogue_ = std::make_unique<Catalogue>((dir_ / "catalogue.sqlite").string());
    std::mt19937_64 random(42);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    constexpr int kGridPoints = 121;
    std::vector<double> abar_times(255);
    for (std::size_t k = 0; k < abar_times.size(); ++k) abar_times[k] = 1e-9 * k;
    std::vector<double> mode_times(64);
    for (std::size_t k = 0; k < mode_times.size(); ++k) mode_times[k] = 4e-9 * k;
    const std::vector<double> mode_amplitudes(mode_times.size() * 65, 1e-4);
    for (int start = 0; start < g_jobs; start += kGridPoints) {
      NewGrid grid;
      grid.id = "grid" + std::to_string(start / kGridPoints);
      grid.definition = "{}";
      grid.create_us = now_us();
      if (first_grid_.empty()) first_grid_ = grid.id;
      std::vector<NewJob> points;
      for (int i = start; i < std::min(g_jobs, start + kGridPoints); ++i) {
        NewJob j;
        j.id = "job" + std::to_string(i);
        j.spec_json = "{}";
        j.spec_hash = "hash" + std::to_string(i);
        j.create_us = grid.create_us;
        j.grid_id = grid.id;
        j.grid_index = i - start;
        j.groups.pbar = 0.25 + 1.5 * u(random);
        j.groups.tbar_pulse = 0.06 + 0.13 * u(random);
        j.groups.mubar = 2.5e-6;
        j.groups.gamma = 5 + 2.5 * u(random);
        j.groups.c1 = 1;
        j.groups.c2 = 0.1;
        points.push_back(j);
      }
      catalogue_->insert_grid(grid, points);
      for (const auto& j : points) {
        catalogue_->start(j.id, now_us());
        StoredSummary s;
        s.summary.groups = j.groups;
        s.summary.groups.time_scale_s = 63.64e-9;
        s.summary.max_abar_first_cycle = 0.02 * j.groups.pbar * (0.5 + u(random));
        s.summary.max_abar = 1.5 * s.summary.max_abar_first_cycle;
        s.summary.energy_injected_J_per_m = 10 * j.groups.pbar * j.groups.tbar_pulse;
        s.summary.dominant_mode_end = 2 + static_cast<int>(40 * u(random));
        s.abar_times = abar_times;
        s.mode_count = 65;
        s.mode_times = mode_times;
        s.mode_amplitudes = mode_amplitudes;
        s.abar_values.assign(abar_times.size(), s.summary.max_abar_first_cycle);
        catalogue_->finish(j.id, 1, JobState::kSucceeded, "", "", "/r/" + j.id, {}, &s, now_us());
      }
    }
  }
  ~Fixture() {
    catalogue_.reset();
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  Catalogue& catalogue() { return *catalogue_; }
  const std::string& first_grid() const { return first_grid_; }

 private:
  fs::path dir_;
  std::unique_ptr<Catalogue> catalogue_;
  std::string first_grid_;
};

Fixture& fixture() {
  static Fixture f;
  return f;
}

RangeCondition range(const std::string& name, double ge, double le) {
  RangeCondition c{name};
  c.ge = ge;
  c.le = le;
  return c;
}

RangeCondition above(const std::string& name, double gt) {
  RangeCondition c{name};
  c.gt = gt;
  return c;
}

// One page (50) of "P-bar in [0.5, 1.5] and gamma > 6", newest first.
void BM_QueryGroupRanges(benchmark::State& state) {
  Catalogue& c = fixture().catalogue();
  JobQuery q;
  q.conditions = {range("pbar", 0.5, 1.5), above("gamma", 6)};
  for (auto _ : state) benchmark::DoNotOptimize(c.query(q));
}
BENCHMARK(BM_QueryGroupRanges)->Unit(benchmark::kMillisecond);

// The same plus a summary filter (max A-bar over the first cycle > 0.01), sorted by it.
void BM_QueryRangesAndSummaryFilterSorted(benchmark::State& state) {
  Catalogue& c = fixture().catalogue();
  JobQuery q;
  q.conditions = {range("pbar", 0.5, 1.5), above("gamma", 6), above("max_abar_first_cycle", 0.01)};
  q.order_by = "max_abar_first_cycle";
  q.descending = true;
  std::size_t rows = 0;
  for (auto _ : state) rows = c.query(q).size();
  state.counters["rows"] = static_cast<double>(rows);
}
BENCHMARK(BM_QueryRangesAndSummaryFilterSorted)->Unit(benchmark::kMillisecond);

// Every match of the sorted query, in pages of 1000 (the largest page).
void BM_QueryAllMatchesPaged(benchmark::State& state) {
  Catalogue& c = fixture().catalogue();
  std::size_t total = 0;
  for (auto _ : state) {
    JobQuery q;
    q.conditions = {range("pbar", 0.5, 1.5), above("gamma", 6),
                    above("max_abar_first_cycle", 0.01)};
    q.order_by = "max_abar_first_cycle";
    q.limit = 1000;
    total = 0;
    for (;;) {
      auto page = c.query(q);
      total += page.size();
      if (static_cast<int>(page.size()) < q.limit) break;
      q.after_key = page.back().sort_key;
      q.after_seq = page.back().job.seq;
    }
  }
  state.counters["rows"] = static_cast<double>(total);
}
BENCHMARK(BM_QueryAllMatchesPaged)->Unit(benchmark::kMillisecond);

// What GetGridReduction reads: the 121 points of one grid with summaries and A-bar samples.
void BM_GridPoints(benchmark::State& state) {
  Catalogue& c = fixture().catalogue();
  for (auto _ : state) benchmark::DoNotOptimize(c.grid_points(fixture().first_grid()));
}
BENCHMARK(BM_GridPoints)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace softshock::server

int main(int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg.rfind("--jobs=", 0) == 0) softshock::server::g_jobs = std::atoi(arg.c_str() + 7);
  }
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
