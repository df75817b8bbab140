// softshockd's configuration from three layers: command-line flags, SOFTSHOCK_* environment
// variables and a config file (--config FILE). Precedence flag > env > file > default. Each
// setting has one name used everywhere: the flag without its dashes (`--max-wall-time`), the
// file key (`max-wall-time`, or `max_wall_time`), the variable (`SOFTSHOCK_MAX_WALL_TIME`).
// Every value of every layer is checked, also one that a higher layer overrides, so a broken
// file or variable is reported instead of lying in wait; errors name the key and its source.
//
// No gRPC here: the loader and its unit tests stay fast and run under the sanitizers.
#pragma once

#include <functional>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "server/daemon.hpp"

namespace softshock::server {

// A setting that is invalid, unknown or inconsistent. what() names the key and where it came
// from ("flag --workers", "env SOFTSHOCK_WORKERS", "file /etc/softshockd.conf:3").
// softshockd exits with status 2 on it.
class ConfigError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct LoadedConfig {
  DaemonConfig config;
  bool help = false;        // --help given: print daemon_config_usage() and exit 0
  bool version = false;     // --version given
  std::string config_file;  // the file read (--config or SOFTSHOCK_CONFIG), empty = none
  // Where each setting's effective value came from (also "config", the file's own source);
  // settings absent here have their default.
  std::map<std::string, std::string> source;
};

// Looks up an environment variable; nullptr when unset. Tests pass a map-backed function.
using EnvLookup = std::function<const char*(const char*)>;

// Reads the three layers. `args` are the command-line arguments without the program name.
// Throws ConfigError. Does not read the token or TLS files (the daemon does, and reports
// unreadable ones as a start-up failure).
LoadedConfig load_daemon_config(const std::vector<std::string>& args, const EnvLookup& env);

// The --help text: every setting with its flag, variable and default, and the file format.
std::string daemon_config_usage();

// One line for the start-up log: every setting's effective value and its source. Paths of
// secrets are shown; the token itself is never read here.
std::string describe_daemon_config(const LoadedConfig& loaded);

// Why `config` must not start, or nothing: a listen address other than loopback (or a unix
// socket) needs a token file or an explicit insecure_no_auth, since anyone who can reach the
// port could otherwise run work and delete results.
std::optional<std::string> exposure_problem(const DaemonConfig& config);

// A warning for the start-up log, or nothing: a bearer token served without TLS on a
// non-loopback address travels in clear text, readable by anyone on the path.
std::optional<std::string> transport_warning(const DaemonConfig& config);

// True for 127.0.0.0/8, ::1, "localhost" and unix sockets; false for 0.0.0.0, [::], host names
// and anything unparsable (refusing is the safe side).
bool is_loopback_listen_address(const std::string& listen);

}  // namespace softshock::server
