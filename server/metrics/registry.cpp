#include "server/metrics/registry.hpp"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <sstream>

namespace softshock::server::metrics {

namespace {

const char* type_name(Type t) {
  switch (t) {
    case Type::kCounter:
      return "counter";
    case Type::kGauge:
      return "gauge";
    case Type::kHistogram:
      return "histogram";
  }
  return "untyped";
}

bool name_char(char c, bool first, bool colon) {
  const bool alpha = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_';
  if (alpha || (colon && c == ':')) return true;
  return !first && c >= '0' && c <= '9';
}

// `{a="x",b="y"}` (with `extra` appended, e.g. le="0.5"), or "" without labels.
void write_labels(std::ostringstream& out, const std::vector<std::string>& names,
                  const LabelValues& values, const std::string& extra = "") {
  if (names.empty() && extra.empty()) return;
  out << '{';
  for (std::size_t i = 0; i < names.size(); ++i) {
    if (i > 0) out << ',';
    out << names[i] << "=\"" << escape_label_value(values[i]) << '"';
  }
  if (!extra.empty()) out << (names.empty() ? "" : ",") << extra;
  out << '}';
}

}  // namespace

void Counter::inc(double by) {
  if (!(by >= 0)) return;  // also NaN
  value_.fetch_add(by, std::memory_order_relaxed);
}

void Gauge::add(double by) {
  value_.fetch_add(by, std::memory_order_relaxed);
}

Histogram::Histogram(std::vector<double> bounds)
    : bounds_(std::move(bounds)), counts_(bounds_.size() + 1, 0) {
  for (std::size_t i = 0; i < bounds_.size(); ++i) {
    if (!std::isfinite(bounds_[i]) || (i > 0 && bounds_[i] <= bounds_[i - 1])) {
      throw std::invalid_argument("histogram bounds must be finite and strictly increasing");
    }
  }
}

void Histogram::observe(double v) {
  if (std::isnan(v)) return;
  // The first bucket whose upper bound is >= v (Prometheus buckets are "less than or equal").
  const auto bucket = static_cast<std::size_t>(std::lower_bound(bounds_.begin(), bounds_.end(), v) -
                                               bounds_.begin());
  std::lock_guard lock(mutex_);
  ++counts_[bucket];
  sum_ += v;
}

Histogram::Snapshot Histogram::snapshot() const {
  Snapshot s;
  s.bounds = bounds_;
  std::lock_guard lock(mutex_);
  std::uint64_t running = 0;
  for (std::size_t i = 0; i < bounds_.size(); ++i) {
    running += counts_[i];
    s.cumulative.push_back(running);
  }
  s.count = running + counts_.back();
  s.sum = sum_;
  return s;
}

std::string escape_label_value(std::string_view v) {
  std::string out;
  out.reserve(v.size());
  for (char c : v) {
    if (c == '\\') {
      out += "\\\\";
    } else if (c == '"') {
      out += "\\\"";
    } else if (c == '\n') {
      out += "\\n";
    } else {
      out += c;
    }
  }
  return out;
}

std::string escape_help(std::string_view v) {
  std::string out;
  out.reserve(v.size());
  for (char c : v) {
    if (c == '\\') {
      out += "\\\\";
    } else if (c == '\n') {
      out += "\\n";
    } else {
      out += c;
    }
  }
  return out;
}

std::string format_value(double v) {
  if (std::isnan(v)) return "NaN";
  if (std::isinf(v)) return v > 0 ? "+Inf" : "-Inf";
  std::array<char, 32> buf{};
  const auto [ptr, ec] = std::to_chars(buf.data(), buf.data() + buf.size(), v);
  if (ec != std::errc()) return "NaN";
  return std::string(buf.data(), ptr);
}

bool valid_metric_name(std::string_view name) {
  if (name.empty()) return false;
  for (std::size_t i = 0; i < name.size(); ++i) {
    if (!name_char(name[i], i == 0, true)) return false;
  }
  return true;
}

bool valid_label_name(std::string_view name) {
  if (name.empty() || name.substr(0, 2) == "__") return false;
  for (std::size_t i = 0; i < name.size(); ++i) {
    if (!name_char(name[i], i == 0, false)) return false;
  }
  return true;
}

Registry::Entry& Registry::add(const std::string& name, const std::string& help, Type type,
                               std::vector<std::string> labels) {
  if (!valid_metric_name(name)) throw std::invalid_argument("invalid metric name '" + name + "'");
  for (const auto& l : labels) {
    if (!valid_label_name(l) || (type == Type::kHistogram && l == "le")) {
      throw std::invalid_argument("metric " + name + ": invalid label name '" + l + "'");
    }
  }
  std::lock_guard lock(mutex_);
  for (const auto& e : entries_) {
    if (e->name == name) throw std::invalid_argument("metric " + name + " registered twice");
  }
  auto entry = std::make_unique<Entry>();
  entry->name = name;
  entry->help = help;
  entry->type = type;
  entry->labels = std::move(labels);
  entries_.push_back(std::move(entry));
  return *entries_.back();
}

Family<Counter>& Registry::counter(const std::string& name, const std::string& help,
                                   std::vector<std::string> labels) {
  Entry& e = add(name, help, Type::kCounter, std::move(labels));
  e.counters = std::make_unique<Family<Counter>>(e.labels.size(),
                                                 [] { return std::make_unique<Counter>(); });
  return *e.counters;
}

Family<Gauge>& Registry::gauge(const std::string& name, const std::string& help,
                               std::vector<std::string> labels) {
  Entry& e = add(name, help, Type::kGauge, std::move(labels));
  e.gauges =
      std::make_unique<Family<Gauge>>(e.labels.size(), [] { return std::make_unique<Gauge>(); });
  return *e.gauges;
}

Family<Histogram>& Registry::histogram(const std::string& name, const std::string& help,
                                       std::vector<std::string> labels,
                                       std::vector<double> bounds) {
  Histogram check(bounds);  // throws for bad bounds before anything is registered
  Entry& e = add(name, help, Type::kHistogram, std::move(labels));
  e.histograms = std::make_unique<Family<Histogram>>(
      e.labels.size(), [bounds] { return std::make_unique<Histogram>(bounds); });
  return *e.histograms;
}

void Registry::sampled(Type type, const std::string& name, const std::string& help,
                       std::vector<std::string> labels, Sampler sample) {
  if (type == Type::kHistogram) throw std::invalid_argument("a sampled histogram: " + name);
  Entry& e = add(name, help, type, std::move(labels));
  e.sampler = std::move(sample);
}

std::string Registry::render() const {
  std::vector<const Entry*> entries;
  {
    std::lock_guard lock(mutex_);
    for (const auto& e : entries_) entries.push_back(e.get());
  }
  std::ostringstream out;
  for (const Entry* e : entries) {
    out << "# HELP " << e->name << ' ' << escape_help(e->help) << '\n';
    out << "# TYPE " << e->name << ' ' << type_name(e->type) << '\n';
    auto sample = [&](const std::string& suffix, const LabelValues& values, double v,
                      const std::string& extra = "") {
      out << e->name << suffix;
      write_labels(out, e->labels, values, extra);
      out << ' ' << format_value(v) << '\n';
    };
    if (e->sampler) {
      std::vector<Sample> samples;
      try {
        samples = e->sampler();
      } catch (const std::exception&) {
        samples.clear();  // this family has no samples in this scrape
      }
      std::sort(samples.begin(), samples.end(),
                [](const Sample& a, const Sample& b) { return a.labels < b.labels; });
      for (const auto& s : samples) {
        if (s.labels.size() == e->labels.size()) sample("", s.labels, s.value);
      }
    } else if (e->counters) {
      e->counters->each([&](const LabelValues& v, const Counter& c) { sample("", v, c.value()); });
    } else if (e->gauges) {
      e->gauges->each([&](const LabelValues& v, const Gauge& g) { sample("", v, g.value()); });
    } else if (e->histograms) {
      e->histograms->each([&](const LabelValues& v, const Histogram& h) {
        const auto snap = h.snapshot();
        for (std::size_t i = 0; i < snap.bounds.size(); ++i) {
          sample("_bucket", v, static_cast<double>(snap.cumulative[i]),
                 "le=\"" + format_value(snap.bounds[i]) + "\"");
        }
        sample("_bucket", v, static_cast<double>(snap.count), "le=\"+Inf\"");
        sample("_sum", v, snap.sum);
        sample("_count", v, static_cast<double>(snap.count));
      });
    }
  }
  return out.str();
}

}  // namespace softshock::server::metrics
