#include "client/format.hpp"

#include <google/protobuf/util/json_util.h>
#include <google/protobuf/util/time_util.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>

#include "client/cli_common.hpp"

namespace softshock::cli {

std::string fmt_num(double value, int significant) {
  if (std::isnan(value)) return "nan";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*g", significant, value);
  return buf;
}

std::string fmt_exact(double v) {
  if (std::isnan(v)) return "nan";
  char buf[32];
  auto [end, ec] = std::to_chars(buf, buf + sizeof buf, v);
  return ec == std::errc() ? std::string(buf, end) : fmt_num(v, 17);
}

std::string fmt_ns(double seconds) {
  return fmt_num(seconds * 1e9) + " ns";
}

std::string fmt_duration(double seconds) {
  char buf[64];
  if (seconds < 0) seconds = 0;
  if (seconds < 60) {
    std::snprintf(buf, sizeof buf, "%.1f s", seconds);
  } else if (seconds < 3600) {
    auto s = static_cast<long>(seconds);
    std::snprintf(buf, sizeof buf, "%ld min %02ld s", s / 60, s % 60);
  } else {
    auto m = static_cast<long>(seconds / 60);
    std::snprintf(buf, sizeof buf, "%ld h %02ld min", m / 60, m % 60);
  }
  return buf;
}

bool timestamp_set(const google::protobuf::Timestamp& ts) {
  return ts.seconds() != 0 || ts.nanos() != 0;
}

double timestamp_seconds(const google::protobuf::Timestamp& ts) {
  return static_cast<double>(ts.seconds()) + ts.nanos() * 1e-9;
}

std::string fmt_timestamp(const google::protobuf::Timestamp& ts) {
  if (!timestamp_set(ts)) return "";
  return google::protobuf::util::TimeUtil::ToString(ts);
}

std::string state_name(int state) {
  if (v1::JobState_IsValid(state)) return v1::JobState_Name(static_cast<v1::JobState>(state));
  return "JobState(" + std::to_string(state) + ")";
}

bool is_terminal(int state) {
  return state == v1::SUCCEEDED || state == v1::FAILED || state == v1::CANCELLED;
}

std::string to_json(const google::protobuf::Message& message, bool pretty, bool proto_names) {
  google::protobuf::util::JsonPrintOptions options;
  options.add_whitespace = pretty;
  options.preserve_proto_field_names = proto_names;
  options.always_print_primitive_fields = true;
  std::string out;
  auto status = google::protobuf::util::MessageToJsonString(message, &out, options);
  if (!status.ok()) throw CliError(kExitFailure, "cannot print JSON: " + status.ToString());
  // add_whitespace leaves no final newline; single-line mode is used for streams (one per line).
  if (!out.empty() && out.back() == '\n') out.pop_back();
  return out;
}

void KeyValues::print(std::FILE* out) const {
  std::size_t width = 0;
  for (const auto& [k, v] : rows_) width = std::max(width, k.size());
  for (const auto& [k, v] : rows_) {
    std::fprintf(out, "%s:%*s %s\n", k.c_str(), static_cast<int>(width - k.size()), "", v.c_str());
  }
}

void print_table(std::FILE* out, const std::vector<std::string>& header,
                 const std::vector<std::vector<std::string>>& rows) {
  std::vector<std::size_t> width(header.size());
  for (std::size_t c = 0; c < header.size(); ++c) width[c] = header[c].size();
  for (const auto& row : rows) {
    for (std::size_t c = 0; c < row.size() && c < width.size(); ++c) {
      width[c] = std::max(width[c], row[c].size());
    }
  }
  // A column is right-aligned when every value in it is a number, so digits line up; text
  // columns (ids, states, labels) read better left-aligned.
  std::vector<bool> numeric(header.size(), !rows.empty());
  for (const auto& row : rows) {
    for (std::size_t c = 0; c < row.size() && c < numeric.size(); ++c) {
      const std::string& v = row[c];
      char* end = nullptr;
      std::strtod(v.c_str(), &end);
      bool num = !v.empty() && end != v.c_str() && (*end == '\0' || std::string(end) == "%");
      if (!num) numeric[c] = false;
    }
  }
  auto line = [&](const std::vector<std::string>& cells) {
    std::string s;
    for (std::size_t c = 0; c < width.size(); ++c) {
      const std::string cell = c < cells.size() ? cells[c] : "";
      std::string pad(width[c] - std::min(width[c], cell.size()), ' ');
      if (c > 0) s += "  ";
      s += numeric[c] ? pad + cell : cell + pad;
    }
    while (!s.empty() && s.back() == ' ') s.pop_back();
    std::fprintf(out, "%s\n", s.c_str());
  };
  line(header);
  for (const auto& row : rows) line(row);
}

std::string join_labels(const google::protobuf::Map<std::string, std::string>& labels) {
  std::vector<std::string> items;
  for (const auto& [k, v] : labels) items.push_back(k + "=" + v);
  std::sort(items.begin(), items.end());
  std::string out;
  for (const auto& s : items) out += (out.empty() ? "" : ",") + s;
  return out;
}

std::string csv_escape(const std::string& field) {
  if (field.find_first_of(",\"\n\r") == std::string::npos) return field;
  std::string out = "\"";
  for (char c : field) {
    if (c == '"') out += '"';
    out += c;
  }
  return out + "\"";
}

ProgressDisplay::ProgressDisplay(std::FILE* out, bool json)
    : out_(out),
      tty_(isatty(fileno(out)) != 0),
      json_(json),
      watch_start_(std::chrono::system_clock::now()) {}

namespace {

int terminal_width(std::FILE* out) {
  winsize ws{};
  if (ioctl(fileno(out), TIOCGWINSZ, &ws) == 0 && ws.ws_col >= 40) return ws.ws_col;
  return 80;
}

// Seconds the job has run: from the server's start time (so a watch attached late shows the
// real figure), to its finish time once terminal.
double elapsed_seconds(const v1::Job& job, std::chrono::system_clock::time_point watch_start) {
  double now =
      std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
  if (timestamp_set(job.start_time())) {
    double end = timestamp_set(job.finish_time()) ? timestamp_seconds(job.finish_time()) : now;
    return std::max(0.0, end - timestamp_seconds(job.start_time()));
  }
  return now - std::chrono::duration<double>(watch_start.time_since_epoch()).count();
}

// Seconds left at the rate so far (elapsed / fraction done), once there is a rate to go by;
// negative when unknown.
double eta_seconds(const v1::Job& job, double elapsed) {
  const double fraction = job.progress().fraction();
  if (job.state() != v1::RUNNING || fraction < 0.005 || fraction >= 1 || elapsed < 0.5) return -1;
  return elapsed * (1 - fraction) / fraction;
}

}  // namespace

std::string ProgressDisplay::describe(const v1::Job& job, bool with_bar) const {
  const auto& p = job.progress();
  const double fraction = std::clamp(p.fraction(), 0.0, 1.0);
  const double elapsed = elapsed_seconds(job, watch_start_);
  const double eta = eta_seconds(job, elapsed);
  const std::string eta_text =
      eta >= 0 ? fmt_duration(eta) : (job.state() == v1::SUCCEEDED ? "0 s" : "-");
  char done[64];
  std::snprintf(done, sizeof done, "%5.1f%%  t = %s / %s", fraction * 100.0,
                fmt_num(p.simulated_time() * 1e9, 4).c_str(),
                fmt_ns(job.spec().run().end_time()).c_str());
  const std::string steps = std::to_string(p.steps()) + " steps";
  if (!with_bar) {
    return job.id() + "  " + state_name(job.state()) + "  " + done + "  " + steps + "  elapsed " +
           fmt_duration(elapsed) + "  ETA " + eta_text;
  }
  // On a terminal the line is redrawn in place: every field has a fixed width, so the bar keeps
  // its place and its width while the numbers grow, and the line never wraps (a wrapped line
  // breaks the carriage-return redraw). The bar gets what the fields leave, 10 to 40 cells; the
  // step count only on terminals of 100 columns or more.
  auto pad = [](std::string text, std::size_t width) {
    if (text.size() < width) text.resize(width, ' ');
    return text;
  };
  const int width = terminal_width(out_);
  const bool wide = width >= 100;
  std::string fields = pad(done, 28) + "  " + (wide ? pad(steps, 16) + "  " : "") +
                       pad(fmt_duration(elapsed), 11) + "  ETA " + eta_text;
  constexpr int kState = 9;      // SUCCEEDED, the longest state name
  constexpr int kEtaWidth = 11;  // "99 h 59 min"
  const int fixed = kState + 2 + 28 + 2 + (wide ? 18 : 0) + 11 + 6 + kEtaWidth;
  const int bar = std::min(40, width - 1 - fixed - 4);
  std::string line = pad(state_name(job.state()), kState) + "  ";
  if (bar >= 10) {
    const int filled = static_cast<int>(std::lround(fraction * bar));
    line += '[';
    line.append(static_cast<std::size_t>(filled), '#');
    line.append(static_cast<std::size_t>(bar - filled), '.');
    line += "]  ";
  }
  return line + fields;
}

void ProgressDisplay::update(const v1::Job& job) {
  if (json_) {
    std::fprintf(out_, "%s\n", to_json(job, false).c_str());
    std::fflush(out_);
    return;
  }
  auto now = std::chrono::steady_clock::now();
  bool state_changed = job.state() != last_state_;
  last_state_ = job.state();
  if (tty_) {
    // Redraw at most ~10 times a second; the server may send far more often.
    if (!state_changed && drawn_ && now - last_print_ < std::chrono::milliseconds(100)) return;
    std::fprintf(out_, "\r\033[K%s", describe(job, true).c_str());
    drawn_ = true;
  } else {
    if (!state_changed && now - last_print_ < std::chrono::seconds(2)) return;
    std::fprintf(out_, "%s\n", describe(job, false).c_str());
  }
  last_print_ = now;
  std::fflush(out_);
}

void ProgressDisplay::finish(const v1::Job& job) {
  if (json_) return;  // update() already printed the terminal message
  if (tty_) {
    std::fprintf(out_, "\r\033[K%s\n", describe(job, true).c_str());
  } else if (job.state() != last_state_ || !is_terminal(last_state_)) {
    std::fprintf(out_, "%s\n", describe(job, false).c_str());
  }
  std::fflush(out_);
}

void write_npy(const std::string& path, const std::vector<double>& values,
               const std::vector<std::size_t>& shape) {
  std::string dims;
  for (std::size_t d : shape) dims += std::to_string(d) + ", ";
  if (shape.size() > 1) dims.resize(dims.size() - 2);  // "(3,)" for 1-D, "(2, 3)" otherwise
  std::string header = "{'descr': '<f8', 'fortran_order': False, 'shape': (" + dims + "), }";
  // Magic (6) + version (2) + length (2) + header + '\n' must be a multiple of 64 bytes.
  std::size_t total = 10 + header.size() + 1;
  header.append((64 - total % 64) % 64, ' ');
  header += '\n';
  std::ofstream f(path, std::ios::binary);
  if (!f) throw CliError(kExitUsage, path + ": " + std::strerror(errno));
  f.write("\x93NUMPY\x01\x00", 8);
  auto len = static_cast<uint16_t>(header.size());
  const char len_bytes[2] = {static_cast<char>(len & 0xff), static_cast<char>(len >> 8)};
  f.write(len_bytes, 2);
  f.write(header.data(), static_cast<std::streamsize>(header.size()));
  // x86-64 and aarch64 Linux are little-endian, matching '<f8'.
  static_assert(std::endian::native == std::endian::little);
  f.write(reinterpret_cast<const char*>(values.data()),
          static_cast<std::streamsize>(values.size() * sizeof(double)));
  if (!f) throw CliError(kExitFailure, path + ": write failed");
}

}  // namespace softshock::cli
