// Prometheus metrics, in the daemon's own few lines: counters, gauges and histograms in labelled
// families, gauges read at scrape time, and the text exposition format 0.0.4 that Prometheus
// scrapes (https://prometheus.io/docs/instrumenting/exposition_formats/): per family one
// `# HELP` and one `# TYPE` line, then its samples; label values escaped (\\ \" \n), help text
// escaped (\\ \n); histograms as cumulative `_bucket{le="..."}` series ending in le="+Inf",
// then `_sum` and `_count`. No gRPC and no HTTP here: the transport renders what this holds.
//
// Families are registered once, at start-up; their series are made on first use. A family keeps
// at most kMaxSeries series: label values past that fold into one series whose values are all
// "overflow", so a bug that labels by something unbounded cannot grow the daemon's memory.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace softshock::server::metrics {

inline constexpr std::size_t kMaxSeries = 2000;

using LabelValues = std::vector<std::string>;

class Counter {
 public:
  // Adds `by` (>= 0; a negative or NaN increment is ignored: counters only grow).
  void inc(double by = 1);
  double value() const { return value_.load(std::memory_order_relaxed); }

 private:
  std::atomic<double> value_{0};
};

class Gauge {
 public:
  void set(double v) { value_.store(v, std::memory_order_relaxed); }
  void add(double by);
  double value() const { return value_.load(std::memory_order_relaxed); }

 private:
  std::atomic<double> value_{0};
};

class Histogram {
 public:
  // `bounds`: the buckets' upper bounds, finite and strictly increasing (+Inf is implied).
  explicit Histogram(std::vector<double> bounds);
  void observe(double v);  // NaN is ignored

  struct Snapshot {
    std::vector<double> bounds;
    std::vector<std::uint64_t> cumulative;  // per bound, observations <= it
    std::uint64_t count = 0;
    double sum = 0;
  };
  Snapshot snapshot() const;

 private:
  const std::vector<double> bounds_;
  mutable std::mutex mutex_;
  std::vector<std::uint64_t> counts_;  // per bucket, not cumulative; one more for +Inf
  double sum_ = 0;
};

enum class Type { kCounter, kGauge, kHistogram };

// The series of one metric, by label values (in the order of the family's label names).
template <typename Metric>
class Family {
 public:
  using Factory = std::function<std::unique_ptr<Metric>()>;
  Family(std::size_t label_count, Factory make) : label_count_(label_count), make_(make) {}

  // The series for these label values, made on first use. Throws std::invalid_argument when
  // the number of values is not the family's number of labels (a programming error).
  Metric& with(const LabelValues& values = {});

  // Every series, by label values (sorted: the exposition is stable).
  template <typename F>
  void each(F&& f) const {
    std::lock_guard lock(mutex_);
    for (const auto& [values, metric] : series_) f(values, *metric);
  }

 private:
  const std::size_t label_count_;
  const Factory make_;
  mutable std::mutex mutex_;
  std::map<LabelValues, std::unique_ptr<Metric>> series_;
};

// One sample of a gauge read at scrape time.
struct Sample {
  LabelValues labels;
  double value = 0;
};
using Sampler = std::function<std::vector<Sample>()>;

class Registry {
 public:
  // Names: [a-zA-Z_:][a-zA-Z0-9_:]*; label names [a-zA-Z_][a-zA-Z0-9_]*, not starting with "__"
  // ("le" is the histograms' own). Throws std::invalid_argument for a bad or repeated name.
  Family<Counter>& counter(const std::string& name, const std::string& help,
                           std::vector<std::string> labels = {});
  Family<Gauge>& gauge(const std::string& name, const std::string& help,
                       std::vector<std::string> labels = {});
  Family<Histogram>& histogram(const std::string& name, const std::string& help,
                               std::vector<std::string> labels, std::vector<double> bounds);
  // A family whose samples `sample` returns at each scrape (a gauge, or a counter kept
  // elsewhere). A sampler that throws leaves its family without samples in that scrape.
  void sampled(Type type, const std::string& name, const std::string& help,
               std::vector<std::string> labels, Sampler sample);

  // The text exposition of every family, in registration order.
  std::string render() const;

  // The content type of render()'s text.
  static constexpr const char* kContentType = "text/plain; version=0.0.4; charset=utf-8";

 private:
  struct Entry {
    std::string name, help;
    Type type;
    std::vector<std::string> labels;
    std::unique_ptr<Family<Counter>> counters;
    std::unique_ptr<Family<Gauge>> gauges;
    std::unique_ptr<Family<Histogram>> histograms;
    Sampler sampler;
  };
  Entry& add(const std::string& name, const std::string& help, Type type,
             std::vector<std::string> labels);

  mutable std::mutex mutex_;
  std::vector<std::unique_ptr<Entry>> entries_;
};

// The exposition format's pieces (tested on their own).
std::string escape_label_value(std::string_view v);
std::string escape_help(std::string_view v);
// Shortest text that reads back as the same double; +Inf, -Inf and NaN as Prometheus spells them.
std::string format_value(double v);
bool valid_metric_name(std::string_view name);
bool valid_label_name(std::string_view name);

template <typename Metric>
Metric& Family<Metric>::with(const LabelValues& values) {
  if (values.size() != label_count_) {
    throw std::invalid_argument("metric series: " + std::to_string(values.size()) +
                                " label value(s) for " + std::to_string(label_count_) +
                                " label(s)");
  }
  std::lock_guard lock(mutex_);
  auto it = series_.find(values);
  if (it != series_.end()) return *it->second;
  if (series_.size() >= kMaxSeries) {
    const LabelValues overflow(label_count_, "overflow");
    auto& slot = series_[overflow];
    if (!slot) slot = make_();
    return *slot;
  }
  return *series_.emplace(values, make_()).first->second;
}

}  // namespace softshock::server::metrics
