// Human-readable and machine-readable output of the CLI: aligned "key: value" blocks, tables,
// numbers with units, protobuf JSON, the watch progress display and .npy files for plotting.
#pragma once

#include <google/protobuf/message.h>
#include <google/protobuf/timestamp.pb.h>

#include <chrono>
#include <cstdio>
#include <string>
#include <utility>
#include <vector>

#include "softshock/v1/service.pb.h"

namespace softshock::cli {

// Six significant digits, no trailing noise ("1.5e-08", "0.25", "16500").
std::string fmt_num(double value, int significant = 6);
// Shortest text that reads back as the same double ("nan" for NaN): CSV output loses nothing.
std::string fmt_exact(double value);
// Seconds shown as nanoseconds, the natural unit of these runs: "361.6 ns".
std::string fmt_ns(double seconds);
// Wall-clock durations: "4.2 s", "3 min 07 s", "2 h 05 min".
std::string fmt_duration(double seconds);
// RFC 3339 in UTC; empty for an unset timestamp.
std::string fmt_timestamp(const google::protobuf::Timestamp& ts);
double timestamp_seconds(const google::protobuf::Timestamp& ts);
bool timestamp_set(const google::protobuf::Timestamp& ts);

// Enum name, or "JobState(7)" for a value this client does not know (AIP-216: clients must
// tolerate new states).
std::string state_name(int state);
bool is_terminal(int state);

// The protobuf JSON mapping (lowerCamelCase names, enums as names, zeros printed too);
// proto_names keeps the proto's snake_case names (the summary: the names softshock-solve prints).
std::string to_json(const google::protobuf::Message& message, bool pretty = true,
                    bool proto_names = false);

// "key:   value" lines with the values aligned in one column.
class KeyValues {
 public:
  void add(std::string key, std::string value) {
    rows_.emplace_back(std::move(key), std::move(value));
  }
  void print(std::FILE* out) const;

 private:
  std::vector<std::pair<std::string, std::string>> rows_;
};

// Whitespace-aligned table; numbers right-aligned, the first column left-aligned.
void print_table(std::FILE* out, const std::vector<std::string>& header,
                 const std::vector<std::vector<std::string>>& rows);

// "k=v,k2=v2", sorted by key (protobuf maps have no order), so the output is stable.
std::string join_labels(const google::protobuf::Map<std::string, std::string>& labels);

// CSV field quoting (RFC 4180) for label values and names.
std::string csv_escape(const std::string& field);

// Progress of a watched job. On a terminal it redraws one line (bar, fraction, simulated time,
// steps, elapsed); otherwise it prints a plain line on state changes and at most every few
// seconds, so logs stay short. With json, every update is one line of protobuf JSON.
class ProgressDisplay {
 public:
  ProgressDisplay(std::FILE* out, bool json);
  void update(const v1::Job& job);
  void finish(const v1::Job& job);  // ends the bar's line and prints the final state

 private:
  std::string describe(const v1::Job& job, bool with_bar) const;

  std::FILE* out_;
  bool tty_;
  bool json_;
  int last_state_ = -1;
  bool drawn_ = false;
  std::chrono::steady_clock::time_point last_print_{};
  std::chrono::system_clock::time_point watch_start_;
};

// Writes a little-endian float64 array in NumPy's .npy format (version 1.0), shape as given.
void write_npy(const std::string& path, const std::vector<double>& values,
               const std::vector<std::size_t>& shape);

}  // namespace softshock::cli
