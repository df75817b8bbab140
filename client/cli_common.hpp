// Pieces every `softshock` command shares: the error type that carries an exit code, a small
// option parser and the parsers for option values. Kept free of gRPC headers so that the
// translation units that only parse or format compile quickly.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace softshock::cli {

// Exit codes are part of the CLI's contract (docs and scripts test them).
inline constexpr int kExitOk = 0;
inline constexpr int kExitFailure = 1;  // server-side failure, unreachable server, job failed
inline constexpr int kExitUsage = 2;  // bad command line or invalid input (incl. INVALID_ARGUMENT)

// Thrown by commands; main() prints "softshock: COMMAND: message" and exits with exit_code.
class CliError : public std::runtime_error {
 public:
  CliError(int exit_code, const std::string& message)
      : std::runtime_error(message), exit_code_(exit_code) {}
  int exit_code() const { return exit_code_; }

 private:
  int exit_code_;
};

[[noreturn]] void usage_error(const std::string& message);

// What a command accepts: options with or without a value; a repeated option keeps every value.
struct OptionSpec {
  std::string name;  // without the leading "--"
  bool takes_value = false;
};

// Parsed command line of one command: positional arguments and options in order of appearance.
class ParsedArgs {
 public:
  std::vector<std::string> positional;

  bool has(const std::string& name) const { return values_.count(name) > 0; }
  // Last value given (options given twice: the last one wins, as in most CLIs).
  std::optional<std::string> get(const std::string& name) const;
  std::vector<std::string> all(const std::string& name) const;
  void add(const std::string& name, const std::string& value) { values_[name].push_back(value); }

 private:
  std::map<std::string, std::vector<std::string>> values_;
};

// Parses args (after the command word) against specs. Accepts "--name value", "--name=value",
// and "--" to end options; anything else starting with "-" (except "-" alone, meaning stdin)
// is a usage error, unless single_dash_words makes "-word" a positional argument.
ParsedArgs parse_options(const std::vector<std::string>& args, const std::vector<OptionSpec>& specs,
                         bool single_dash_words = false);

// Value parsers: each throws a usage error naming the option on bad input.
int64_t parse_int(const std::string& option, const std::string& text);
double parse_double(const std::string& option, const std::string& text);
// A time in seconds; a unit suffix s, ms, us or ns is accepted ("40ns" = 4e-8).
double parse_time_seconds(const std::string& option, const std::string& text);
// "key=value" with a non-empty key.
std::pair<std::string, std::string> parse_label(const std::string& option, const std::string& text);
// "NXxNY", e.g. "256x256".
std::pair<int, int> parse_raster(const std::string& option, const std::string& text);

// Whole file as a string; "-" reads stdin. Throws CliError(kExitUsage) when unreadable: a file
// the user names is input, so a missing one is a usage problem, not a server one.
std::string read_file(const std::string& path);

std::string trim(std::string_view text);

// Random version-4 UUID, used as the default request_id so a retried submit stays idempotent.
std::string make_uuid();

}  // namespace softshock::cli
