#include "client/cli_common.hpp"

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>
#include <iterator>
#include <random>
#include <sstream>

namespace softshock::cli {

void usage_error(const std::string& message) {
  throw CliError(kExitUsage, message);
}

std::optional<std::string> ParsedArgs::get(const std::string& name) const {
  auto it = values_.find(name);
  if (it == values_.end() || it->second.empty()) return std::nullopt;
  return it->second.back();
}

std::vector<std::string> ParsedArgs::all(const std::string& name) const {
  auto it = values_.find(name);
  return it == values_.end() ? std::vector<std::string>{} : it->second;
}

ParsedArgs parse_options(const std::vector<std::string>& args, const std::vector<OptionSpec>& specs,
                         bool single_dash_words) {
  ParsedArgs parsed;
  bool options_ended = false;
  for (std::size_t i = 0; i < args.size(); ++i) {
    const std::string& arg = args[i];
    if (options_ended || arg == "-" || arg.size() < 2 || arg[0] != '-' ||
        (single_dash_words && arg[1] != '-')) {
      parsed.positional.push_back(arg);
      continue;
    }
    if (arg == "--") {
      options_ended = true;
      continue;
    }
    if (arg.rfind("--", 0) != 0) {
      // Negative numbers are never positional arguments here, so a single dash is a mistake.
      usage_error("unknown option " + arg);
    }
    std::string name = arg.substr(2);
    std::optional<std::string> inline_value;
    if (auto eq = name.find('='); eq != std::string::npos) {
      inline_value = name.substr(eq + 1);
      name.resize(eq);
    }
    const OptionSpec* spec = nullptr;
    for (const auto& s : specs) {
      if (s.name == name) spec = &s;
    }
    if (spec == nullptr) usage_error("unknown option --" + name);
    if (!spec->takes_value) {
      if (inline_value) usage_error("option --" + name + " takes no value");
      parsed.add(name, "");
      continue;
    }
    if (inline_value) {
      parsed.add(name, *inline_value);
    } else if (i + 1 < args.size()) {
      parsed.add(name, args[++i]);
    } else {
      usage_error("option --" + name + " needs a value");
    }
  }
  return parsed;
}

int64_t parse_int(const std::string& option, const std::string& text) {
  int64_t value = 0;
  const char* end = text.data() + text.size();
  auto [ptr, ec] = std::from_chars(text.data(), end, value);
  if (ec != std::errc() || ptr != end || text.empty()) {
    usage_error("--" + option + ": not an integer: '" + text + "'");
  }
  return value;
}

double parse_double(const std::string& option, const std::string& text) {
  // strtod rather than from_chars: it accepts the forms users type ("1e-8", "+2", ".5").
  errno = 0;
  char* end = nullptr;
  double value = std::strtod(text.c_str(), &end);
  if (text.empty() || end != text.c_str() + text.size() || errno == ERANGE ||
      !std::isfinite(value)) {
    usage_error("--" + option + ": not a finite number: '" + text + "'");
  }
  return value;
}

double parse_time_seconds(const std::string& option, const std::string& text) {
  static const std::pair<const char*, double> kUnits[] = {
      {"ns", 1e-9}, {"us", 1e-6}, {"ms", 1e-3}, {"s", 1.0}};
  for (const auto& [suffix, scale] : kUnits) {
    std::string_view sv(text);
    std::size_t n = std::strlen(suffix);
    if (sv.size() > n && sv.substr(sv.size() - n) == suffix) {
      return parse_double(option, std::string(sv.substr(0, sv.size() - n))) * scale;
    }
  }
  return parse_double(option, text);
}

std::pair<std::string, std::string> parse_label(const std::string& option,
                                                const std::string& text) {
  auto eq = text.find('=');
  if (eq == std::string::npos || eq == 0) {
    usage_error("--" + option + ": expected key=value, got '" + text + "'");
  }
  return {text.substr(0, eq), text.substr(eq + 1)};
}

std::pair<int, int> parse_raster(const std::string& option, const std::string& text) {
  auto x = text.find_first_of("xX");
  if (x == std::string::npos) usage_error("--" + option + ": expected NXxNY, e.g. 256x256");
  int64_t nx = parse_int(option, text.substr(0, x));
  int64_t ny = parse_int(option, text.substr(x + 1));
  if (nx < 1 || ny < 1 || nx > 100000 || ny > 100000) {
    usage_error("--" + option + ": raster sizes must be between 1 and 100000");
  }
  return {static_cast<int>(nx), static_cast<int>(ny)};
}

std::string read_file(const std::string& path) {
  if (path == "-") {
    std::ostringstream ss;
    ss << std::cin.rdbuf();
    return ss.str();
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) throw CliError(kExitUsage, path + ": " + std::strerror(errno));
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

std::string trim(std::string_view text) {
  const char* ws = " \t\r\n";
  auto b = text.find_first_not_of(ws);
  if (b == std::string_view::npos) return {};
  auto e = text.find_last_not_of(ws);
  return std::string(text.substr(b, e - b + 1));
}

std::string make_uuid() {
  std::random_device rd;
  std::mt19937_64 gen((static_cast<uint64_t>(rd()) << 32) ^ rd());
  uint64_t hi = gen(), lo = gen();
  hi = (hi & 0xffffffffffff0fffULL) | 0x0000000000004000ULL;  // version 4
  lo = (lo & 0x3fffffffffffffffULL) | 0x8000000000000000ULL;  // RFC 4122 variant
  char buf[37];
  std::snprintf(buf, sizeof buf, "%08x-%04x-%04x-%04x-%012llx", static_cast<unsigned>(hi >> 32),
                static_cast<unsigned>((hi >> 16) & 0xffff), static_cast<unsigned>(hi & 0xffff),
                static_cast<unsigned>(lo >> 48),
                static_cast<unsigned long long>(lo & 0xffffffffffffULL));
  return buf;
}

}  // namespace softshock::cli
