#include "server/daemon_config.hpp"

#include <arpa/inet.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <fstream>
#include <sstream>

#include "server/policy/users.hpp"

namespace softshock::server {

namespace {

// --- value parsers: throw std::invalid_argument with what the value should have been -------

long long parse_int(const std::string& v, long long lo, long long hi) {
  long long x = 0;
  const char* end = v.data() + v.size();
  const auto [ptr, ec] = std::from_chars(v.data(), end, x);
  if (v.empty() || ec != std::errc() || ptr != end || x < lo || x > hi) {
    throw std::invalid_argument("expects an integer in " + std::to_string(lo) + ".." +
                                std::to_string(hi));
  }
  return x;
}

double parse_seconds(const std::string& v) {
  double x = 0;
  const char* end = v.data() + v.size();
  const auto [ptr, ec] = std::from_chars(v.data(), end, x);
  if (v.empty() || ec != std::errc() || ptr != end || !std::isfinite(x) || x < 0) {
    throw std::invalid_argument("expects a number of seconds >= 0");
  }
  return x;
}

std::string show_number(double x);

// Bytes: an integer with an optional binary suffix K, M, G or T (KiB, MiB, ...; "B" optional).
double parse_bytes(const std::string& v) {
  std::string digits = v, suffix;
  while (!digits.empty() && std::isalpha(static_cast<unsigned char>(digits.back()))) {
    suffix.insert(suffix.begin(), digits.back());
    digits.pop_back();
  }
  if (suffix.size() > 1 && (suffix.back() == 'B' || suffix.back() == 'b')) suffix.pop_back();
  if (suffix == "iB" || suffix == "i") suffix.clear();
  if (suffix.size() == 2 && suffix[1] == 'i') suffix.pop_back();
  double scale = 1;
  if (suffix == "K" || suffix == "k") {
    scale = 1024.0;
  } else if (suffix == "M") {
    scale = 1024.0 * 1024;
  } else if (suffix == "G") {
    scale = 1024.0 * 1024 * 1024;
  } else if (suffix == "T") {
    scale = 1024.0 * 1024 * 1024 * 1024;
  } else if (!suffix.empty() && suffix != "B") {
    digits.clear();  // an unknown unit
  }
  long long x = 0;
  const char* end = digits.data() + digits.size();
  const auto [ptr, ec] = std::from_chars(digits.data(), end, x);
  if (digits.empty() || ec != std::errc() || ptr != end || x < 1) {
    throw std::invalid_argument("expects a size in bytes >= 1, optionally with K, M, G or T");
  }
  return static_cast<double>(x) * scale;
}

std::string show_bytes(double b) {
  const char* units[] = {"", "K", "M", "G", "T"};
  int u = 0;
  while (u < 4 && b >= 1024 && std::fmod(b, 1024) == 0) {
    b /= 1024;
    ++u;
  }
  return show_number(b) + units[u];
}

bool parse_bool(const std::string& v) {
  std::string s = v;
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  if (s == "true" || s == "1" || s == "yes" || s == "on") return true;
  if (s == "false" || s == "0" || s == "no" || s == "off") return false;
  throw std::invalid_argument("expects true or false");
}

std::string parse_required(const std::string& v) {
  if (v.empty()) throw std::invalid_argument("expects a non-empty value");
  return v;
}

std::string show_number(double x) {
  std::array<char, 32> buf{};
  const auto [ptr, ec] = std::to_chars(buf.data(), buf.data() + buf.size(), x);
  return ec == std::errc() ? std::string(buf.data(), ptr) : std::to_string(x);
}

std::string show_path(const std::string& p) {
  return p.empty() ? "(none)" : p;
}

// --- the settings -------------------------------------------------------------------------

// One daemon setting. A new DaemonConfig field that users may set gets a row here and nowhere
// else: flags, variables, file keys, --help and the start-up log all come from this table.
struct Setting {
  const char* key;      // flag without dashes = file key; SOFTSHOCK_ + upper-case = variable
  const char* metavar;  // nullptr: a switch (`--key` alone means true)
  const char* help;
  void (*apply)(DaemonConfig&, const std::string&);  // throws std::invalid_argument
  std::string (*show)(const DaemonConfig&);
};

// Pass-through lambdas become the function pointers of the table.
const std::vector<Setting>& settings() {
  static const std::vector<Setting> table = {
      {"data-dir", "DIR", "catalogue and results (default ./data; created if missing)",
       [](DaemonConfig& c, const std::string& v) { c.data_dir = parse_required(v); },
       [](const DaemonConfig& c) { return c.data_dir; }},
      {"listen", "ADDR", "address to serve on (default 127.0.0.1:50051; 127.0.0.1:0 = any port)",
       [](DaemonConfig& c, const std::string& v) { c.listen = parse_required(v); },
       [](const DaemonConfig& c) { return c.listen; }},
      {"port-file", "FILE", "write the bound port number here once listening",
       [](DaemonConfig& c, const std::string& v) { c.port_file = v; },
       [](const DaemonConfig& c) { return show_path(c.port_file); }},
      {"workers", "N", "jobs run at once (default: hardware threads)",
       [](DaemonConfig& c, const std::string& v) {
         c.workers = static_cast<int>(parse_int(v, 1, 4096));
       },
       [](const DaemonConfig& c) {
         return c.workers > 0 ? std::to_string(c.workers) : std::string("hardware-threads");
       }},
      {"max-queued", "N", "waiting jobs before SubmitJob answers RESOURCE_EXHAUSTED (default 1000)",
       [](DaemonConfig& c, const std::string& v) {
         c.max_queued = static_cast<std::size_t>(parse_int(v, 1, 100'000'000));
       },
       [](const DaemonConfig& c) { return std::to_string(c.max_queued); }},
      {"token-file", "FILE",
       "require 'authorization: Bearer <token>'; the token in FILE is the user token-user, an "
       "admin",
       [](DaemonConfig& c, const std::string& v) { c.token_file = v; },
       [](const DaemonConfig& c) { return show_path(c.token_file); }},
      {"token-user", "NAME", "the user token-file's token names (default 'default')",
       [](DaemonConfig& c, const std::string& v) {
         if (!valid_user_name(v)) {
           throw std::invalid_argument(
               "expects a user name: 1 to 64 of A-Z a-z 0-9 . _ -, not starting with . or -");
         }
         c.token_user = v;
       },
       [](const DaemonConfig& c) { return c.token_user; }},
      {"users-file", "FILE",
       "users who may call, one 'user:token[:role]' line each (role user or admin); same file "
       "rules as token-file; reread on SIGHUP",
       [](DaemonConfig& c, const std::string& v) { c.users_file = v; },
       [](const DaemonConfig& c) { return show_path(c.users_file); }},
      {"insecure-no-auth", nullptr,
       "serve a non-loopback address without token-file (only behind another auth layer)",
       [](DaemonConfig& c, const std::string& v) { c.insecure_no_auth = parse_bool(v); },
       [](const DaemonConfig& c) { return std::string(c.insecure_no_auth ? "true" : "false"); }},
      {"tls-cert", "FILE", "PEM certificate chain (with tls-key: serve TLS)",
       [](DaemonConfig& c, const std::string& v) { c.tls_cert = v; },
       [](const DaemonConfig& c) { return show_path(c.tls_cert); }},
      {"tls-key", "FILE", "PEM private key",
       [](DaemonConfig& c, const std::string& v) { c.tls_key = v; },
       [](const DaemonConfig& c) { return show_path(c.tls_key); }},
      {"http-listen", "ADDR",
       "serve the dashboard and its JSON API here, e.g. 127.0.0.1:8080 (same token and TLS as "
       "gRPC; default: off)",
       [](DaemonConfig& c, const std::string& v) { c.http_listen = v; },
       [](const DaemonConfig& c) { return show_path(c.http_listen); }},
      {"http-port-file", "FILE", "write the dashboard's bound port here once listening",
       [](DaemonConfig& c, const std::string& v) { c.http_port_file = v; },
       [](const DaemonConfig& c) { return show_path(c.http_port_file); }},
      {"metrics-listen", "ADDR",
       "serve Prometheus metrics at /metrics here, without a token, e.g. 0.0.0.0:9464 (default: "
       "off)",
       [](DaemonConfig& c, const std::string& v) { c.metrics_listen = v; },
       [](const DaemonConfig& c) { return show_path(c.metrics_listen); }},
      {"metrics-port-file", "FILE", "write the metrics listener's bound port here",
       [](DaemonConfig& c, const std::string& v) { c.metrics_port_file = v; },
       [](const DaemonConfig& c) { return show_path(c.metrics_port_file); }},
      {"max-concurrent-rpcs", "N",
       "calls served at once; more get RESOURCE_EXHAUSTED (default 256)",
       [](DaemonConfig& c, const std::string& v) {
         c.max_concurrent_rpcs = static_cast<int>(parse_int(v, 4, 100'000));
       },
       [](const DaemonConfig& c) { return std::to_string(c.max_concurrent_rpcs); }},
      {"max-elements", "N", "largest mesh a job may use (default 2000000)",
       [](DaemonConfig& c, const std::string& v) {
         c.max_elements = static_cast<int>(parse_int(v, 1, 2'000'000'000));
       },
       [](const DaemonConfig& c) { return std::to_string(c.max_elements); }},
      {"max-end-time", "SECONDS", "longest simulated end time (default 1e-5)",
       [](DaemonConfig& c, const std::string& v) { c.max_end_time_s = parse_seconds(v); },
       [](const DaemonConfig& c) { return show_number(c.max_end_time_s); }},
      {"max-steps", "N", "refuse jobs estimated to need more time steps (default 10000000)",
       [](DaemonConfig& c, const std::string& v) {
         c.max_steps = static_cast<double>(parse_int(v, 1, 1'000'000'000'000));
       },
       [](const DaemonConfig& c) { return show_number(c.max_steps); }},
      {"max-job-memory", "BYTES", "refuse jobs estimated to need more memory (default 4G)",
       [](DaemonConfig& c, const std::string& v) { c.max_job_memory_bytes = parse_bytes(v); },
       [](const DaemonConfig& c) { return show_bytes(c.max_job_memory_bytes); }},
      {"max-job-disk", "BYTES", "refuse jobs estimated to write a larger result (default 16G)",
       [](DaemonConfig& c, const std::string& v) { c.max_job_disk_bytes = parse_bytes(v); },
       [](const DaemonConfig& c) { return show_bytes(c.max_job_disk_bytes); }},
      {"max-wall-time", "SECONDS", "wall-clock limit per job, 0 = none (default 21600 = 6 h)",
       [](DaemonConfig& c, const std::string& v) { c.max_wall_time_s = parse_seconds(v); },
       [](const DaemonConfig& c) { return show_number(c.max_wall_time_s); }},
      {"checkpoint-interval", "SECONDS",
       "wall time between a running job's restartable checkpoints, 0 = none (default 600)",
       [](DaemonConfig& c, const std::string& v) { c.checkpoint_interval_s = parse_seconds(v); },
       [](const DaemonConfig& c) { return show_number(c.checkpoint_interval_s); }},
      {"solver-threads", "N", "element-loop threads per job (default 1)",
       [](DaemonConfig& c, const std::string& v) {
         c.solver_threads = static_cast<int>(parse_int(v, 1, 1024));
       },
       [](const DaemonConfig& c) { return std::to_string(c.solver_threads); }},
      {"mesh-cache-bytes", "BYTES",
       "meshes kept in DATA/cache/meshes for reuse, least recently used evicted first; 0 = "
       "mesh every job (default 1073741824 = 1 GiB)",
       [](DaemonConfig& c, const std::string& v) {
         c.mesh_cache_bytes = parse_int(v, 0, 1LL << 50);
       },
       [](const DaemonConfig& c) { return std::to_string(c.mesh_cache_bytes); }},
      {"min-free-bytes", "BYTES",
       "free space the data folder keeps: below it no job starts and no submission or upload "
       "is taken (default 256M)",
       [](DaemonConfig& c, const std::string& v) { c.min_free_bytes = parse_bytes(v); },
       [](const DaemonConfig& c) { return show_bytes(c.min_free_bytes); }},
      {"max-queued-per-user", "N",
       "waiting jobs (grid points included) one user may have (default 500)",
       [](DaemonConfig& c, const std::string& v) {
         c.quotas.max_queued_per_user = parse_int(v, 1, 100'000'000);
       },
       [](const DaemonConfig& c) { return std::to_string(c.quotas.max_queued_per_user); }},
      {"max-meshes", "N", "uploaded meshes stored, all users together (default 1000)",
       [](DaemonConfig& c, const std::string& v) {
         c.quotas.max_meshes = parse_int(v, 1, 100'000'000);
       },
       [](const DaemonConfig& c) { return std::to_string(c.quotas.max_meshes); }},
      {"max-meshes-per-user", "N", "uploaded meshes one user may store (default 100)",
       [](DaemonConfig& c, const std::string& v) {
         c.quotas.max_meshes_per_user = parse_int(v, 1, 100'000'000);
       },
       [](const DaemonConfig& c) { return std::to_string(c.quotas.max_meshes_per_user); }},
      {"max-mesh-bytes", "BYTES", "bytes of uploaded meshes, all users together (default 8G)",
       [](DaemonConfig& c, const std::string& v) {
         c.quotas.max_mesh_bytes = static_cast<std::int64_t>(parse_bytes(v));
       },
       [](const DaemonConfig& c) {
         return show_bytes(static_cast<double>(c.quotas.max_mesh_bytes));
       }},
      {"max-mesh-bytes-per-user", "BYTES",
       "bytes of uploaded meshes one user may store (default 1G)",
       [](DaemonConfig& c, const std::string& v) {
         c.quotas.max_mesh_bytes_per_user = static_cast<std::int64_t>(parse_bytes(v));
       },
       [](const DaemonConfig& c) {
         return show_bytes(static_cast<double>(c.quotas.max_mesh_bytes_per_user));
       }},
      {"max-attempts", "N", "runs a job gets when the daemon is killed under it (default 3)",
       [](DaemonConfig& c, const std::string& v) {
         c.max_attempts = static_cast<int>(parse_int(v, 1, 1000));
       },
       [](const DaemonConfig& c) { return std::to_string(c.max_attempts); }},
      // The slurm executor (docs/cluster.md).
      {"executor", "local|slurm", "where jobs run: in-process workers or Slurm (default local)",
       [](DaemonConfig& c, const std::string& v) {
         if (v != "local" && v != "slurm") throw std::invalid_argument("expects local or slurm");
         c.executor = v;
       },
       [](const DaemonConfig& c) { return c.executor; }},
      {"slurm-partition", "NAME", "sbatch --partition (default: the cluster's)",
       [](DaemonConfig& c, const std::string& v) { c.slurm_partition = v; },
       [](const DaemonConfig& c) { return show_path(c.slurm_partition); }},
      {"slurm-account", "NAME", "sbatch --account (default: the user's)",
       [](DaemonConfig& c, const std::string& v) { c.slurm_account = v; },
       [](const DaemonConfig& c) { return show_path(c.slurm_account); }},
      {"slurm-time-limit", "TIME",
       "sbatch --time per job, e.g. 30 or 2:00:00 (default: partition's)",
       [](DaemonConfig& c, const std::string& v) { c.slurm_time_limit = v; },
       [](const DaemonConfig& c) { return show_path(c.slurm_time_limit); }},
      {"slurm-shared-dir", "DIR",
       "specs and results, seen by the compute nodes (default DATA/slurm)",
       [](DaemonConfig& c, const std::string& v) { c.slurm_shared_dir = v; },
       [](const DaemonConfig& c) { return show_path(c.slurm_shared_dir); }},
      // Repeatable: each occurrence adds one option (all layers add up, file first).
      {"slurm-sbatch-arg", "ARG", "one more sbatch option, verbatim; repeatable",
       [](DaemonConfig& c, const std::string& v) {
         c.slurm_sbatch_args.push_back(parse_required(v));
       },
       [](const DaemonConfig& c) {
         std::string all;
         for (const auto& a : c.slurm_sbatch_args) all += (all.empty() ? "" : ",") + a;
         return show_path(all);
       }},
      {"slurm-solver", "PATH", "softshock-solve as the compute nodes find it (default: on PATH)",
       [](DaemonConfig& c, const std::string& v) { c.slurm_solver = parse_required(v); },
       [](const DaemonConfig& c) { return c.slurm_solver; }},
      {"slurm-poll-interval", "SECONDS", "how often Slurm is asked for job states (default 1)",
       [](DaemonConfig& c, const std::string& v) {
         c.slurm_poll_s = std::max(0.05, parse_seconds(v));
       },
       [](const DaemonConfig& c) { return show_number(c.slurm_poll_s); }},
  };
  return table;
}

constexpr const char* kConfigKey = "config";  // flag and variable only: a file names no file

std::string env_name(const std::string& key) {
  std::string name = "SOFTSHOCK_";
  for (char c : key) name += c == '-' ? '_' : static_cast<char>(std::toupper(c));
  return name;
}

const Setting* find_setting(const std::string& key) {
  for (const auto& s : settings()) {
    if (key == s.key) return &s;
  }
  return nullptr;
}

// One value from one layer, in the order it is applied.
struct Assignment {
  const Setting* setting;
  std::string value;
  std::string source;  // "flag --workers", "env SOFTSHOCK_WORKERS", "file PATH:LINE"
};

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r\n");
  if (b == std::string::npos) return "";
  const auto e = s.find_last_not_of(" \t\r\n");
  return s.substr(b, e - b + 1);
}

// The right-hand side of `key = value`: a "basic string" (\" \\ \t \n escapes), a 'literal
// string', or a bare word; a # outside quotes starts a comment. Throws std::invalid_argument.
std::string parse_file_value(const std::string& raw) {
  std::string out;
  std::size_t i = 0;
  if (!raw.empty() && (raw[0] == '"' || raw[0] == '\'')) {
    const char quote = raw[0];
    for (i = 1; i < raw.size() && raw[i] != quote; ++i) {
      if (quote == '"' && raw[i] == '\\' && i + 1 < raw.size()) {
        const char e = raw[++i];
        if (e == 'n') {
          out += '\n';
        } else if (e == 't') {
          out += '\t';
        } else if (e == '"' || e == '\\') {
          out += e;
        } else {
          throw std::invalid_argument(std::string("unknown escape \\") + e);
        }
      } else {
        out += raw[i];
      }
    }
    if (i == raw.size()) throw std::invalid_argument("unterminated string");
    const std::string rest = trim(raw.substr(i + 1));
    if (!rest.empty() && rest[0] != '#') {
      throw std::invalid_argument("unexpected text after the closing quote");
    }
    return out;
  }
  return trim(raw.substr(0, raw.find('#')));
}

std::vector<Assignment> read_config_file(const std::string& path, const std::string& named_by) {
  std::ifstream in(path);
  if (!in) throw ConfigError("cannot read config file " + path + " (" + named_by + ")");
  std::vector<Assignment> out;
  std::map<std::string, int> first_line;
  std::string line;
  for (int n = 1; std::getline(in, line); ++n) {
    const std::string where = "file " + path + ":" + std::to_string(n);
    const std::string text = trim(line);
    if (text.empty() || text[0] == '#') continue;
    if (text[0] == '[') {
      throw ConfigError(where + ": sections are not supported; write key = value lines");
    }
    const auto eq = text.find('=');
    if (eq == std::string::npos) throw ConfigError(where + ": expected key = value");
    std::string key = trim(text.substr(0, eq));
    std::replace(key.begin(), key.end(), '_', '-');  // TOML habit: max_wall_time
    if (key == kConfigKey) {
      throw ConfigError(where + ": 'config' cannot be set inside a config file");
    }
    const Setting* s = find_setting(key);
    if (s == nullptr) throw ConfigError(where + ": unknown key '" + key + "'");
    if (auto [it, fresh] = first_line.emplace(key, n); !fresh) {
      throw ConfigError(where + ": " + key + " is already set at line " +
                        std::to_string(it->second));
    }
    try {
      out.push_back({s, parse_file_value(trim(text.substr(eq + 1))), where});
    } catch (const std::invalid_argument& e) {
      throw ConfigError(where + ": " + key + ": " + e.what());
    }
  }
  return out;
}

void apply(LoadedConfig& loaded, const Assignment& a) {
  try {
    a.setting->apply(loaded.config, a.value);
  } catch (const std::invalid_argument& e) {
    throw ConfigError(std::string(a.setting->key) + " = '" + a.value + "' (" + a.source +
                      "): " + e.what());
  }
  loaded.source[a.setting->key] = a.source;
}

std::string source_of(const LoadedConfig& loaded, const std::string& key) {
  const auto it = loaded.source.find(key);
  return it == loaded.source.end() ? "default" : it->second;
}

}  // namespace

LoadedConfig load_daemon_config(const std::vector<std::string>& args, const EnvLookup& env) {
  LoadedConfig loaded;

  // Flags first (to find --config and --help), applied last.
  std::vector<Assignment> flags;
  std::string config_file, config_source;
  for (std::size_t i = 0; i < args.size(); ++i) {
    std::string arg = args[i];
    if (arg == "--help" || arg == "-h") {
      loaded.help = true;
      return loaded;
    }
    if (arg == "--version") {
      loaded.version = true;
      return loaded;
    }
    if (arg.rfind("--", 0) != 0) throw ConfigError("unexpected argument '" + arg + "'");
    std::optional<std::string> value;
    if (const auto eq = arg.find('='); eq != std::string::npos) {
      value = arg.substr(eq + 1);
      arg = arg.substr(0, eq);
    }
    const std::string key = arg.substr(2);
    const Setting* s = find_setting(key);
    if (s == nullptr && key != kConfigKey) throw ConfigError("unknown flag " + arg);
    if (!value) {
      if (s != nullptr && s->metavar == nullptr) {
        value = "true";
      } else if (i + 1 < args.size()) {
        value = args[++i];
      } else {
        throw ConfigError(arg + " needs a value");
      }
    }
    if (s == nullptr) {  // --config
      config_file = *value;
      config_source = "flag " + arg;
    } else {
      flags.push_back({s, *value, "flag " + arg});
    }
  }
  if (config_source.empty()) {
    const std::string name = env_name(kConfigKey);
    if (const char* v = env(name.c_str()); v != nullptr && *v != '\0') {
      config_file = v;
      config_source = "env " + name;
    }
  }
  if (!config_source.empty() && config_file.empty()) {
    throw ConfigError("config = '' (" + config_source + "): expects a file name");
  }

  if (!config_file.empty()) {
    loaded.config_file = config_file;
    loaded.source[kConfigKey] = config_source;
    for (const auto& a : read_config_file(config_file, config_source)) apply(loaded, a);
  }
  // An empty variable counts as unset, as with the client's SOFTSHOCK_SERVER: compose files
  // and shell scripts often pass VAR= for "not given".
  for (const auto& s : settings()) {
    const std::string name = env_name(s.key);
    if (const char* v = env(name.c_str()); v != nullptr && *v != '\0') {
      apply(loaded, {&s, v, "env " + name});
    }
  }
  for (const auto& a : flags) apply(loaded, a);  // in order: the last of a repeated flag wins

  const DaemonConfig& c = loaded.config;
  if (c.tls_cert.empty() != c.tls_key.empty()) {
    throw ConfigError("tls-cert (" + source_of(loaded, "tls-cert") + ") and tls-key (" +
                      source_of(loaded, "tls-key") + ") go together: set both or neither");
  }
  if (auto problem = exposure_problem(c)) {
    const char* key = is_loopback_listen_address(c.listen) ? "http-listen" : "listen";
    throw ConfigError(*problem + " [" + key + " from " + source_of(loaded, key) + "]");
  }
  return loaded;
}

std::string daemon_config_usage() {
  std::ostringstream s;
  s << "usage: softshockd [flags]\n\n"
       "Runs softshock simulations submitted over gRPC (softshock.v1.SimulationService).\n\n"
       "Settings (flag, environment variable, meaning):\n"
       "  --config FILE  (SOFTSHOCK_CONFIG)\n"
       "      read settings from FILE (format below)\n";
  for (const auto& st : settings()) {
    s << "  --" << st.key;
    if (st.metavar != nullptr) s << " " << st.metavar;
    s << "  (" << env_name(st.key) << ")\n      " << st.help << "\n";
  }
  s << "  --help     this text\n"
       "  --version  print the version\n\n"
       "A listen address other than loopback (0.0.0.0, [::], a host name) needs token-file,\n"
       "users-file or insecure-no-auth: softshockd refuses to start open to the network.\n\n"
       "Precedence: flag > environment variable > config file > default. A flag may be given\n"
       "as --key VALUE or --key=VALUE; repeated, the last one wins. An empty variable counts as\n"
       "unset; other SOFTSHOCK_* variables are ignored. Switches take true/false (also 1/0,\n"
       "yes/no, on/off) as --key=VALUE, in a variable or in the file.\n\n"
       "Config file: one `key = value` per line, keys as the flags without dashes ('_' may\n"
       "replace '-'), each key at most once; values bare, \"quoted\" (\\\" \\\\ \\t \\n) or\n"
       "'literal'; '#' starts a comment; no [sections]. Example:\n"
       "    listen = \"0.0.0.0:50051\"\n"
       "    token-file = /run/secrets/softshock_token\n"
       "    workers = 4   # jobs at once\n\n"
       "Exit status: 0 after SIGTERM/SIGINT, 1 when it cannot start, 2 for an invalid setting\n"
       "(the message names the key and where it came from).\n";
  return s.str();
}

std::string describe_daemon_config(const LoadedConfig& loaded) {
  std::ostringstream s;
  s << "configuration: " << kConfigKey << "=" << show_path(loaded.config_file) << " ["
    << source_of(loaded, kConfigKey) << "]";
  for (const auto& st : settings()) {
    s << " " << st.key << "=" << st.show(loaded.config) << " [" << source_of(loaded, st.key) << "]";
  }
  return s.str();
}

bool is_loopback_listen_address(const std::string& listen) {
  if (listen.rfind("unix:", 0) == 0 || listen.rfind("unix-abstract:", 0) == 0) return true;
  std::string host = listen;
  for (const char* scheme : {"ipv4:", "ipv6:", "dns:"}) {
    if (host.rfind(scheme, 0) == 0) host = host.substr(std::string(scheme).size());
  }
  if (!host.empty() && host[0] == '[') {  // [v6]:port
    const auto close = host.find(']');
    if (close == std::string::npos) return false;
    host = host.substr(1, close - 1);
  } else if (const auto colon = host.rfind(':'); colon != std::string::npos) {
    host = host.substr(0, colon);
  }
  if (host == "localhost") return true;
  in_addr v4{};
  if (::inet_pton(AF_INET, host.c_str(), &v4) == 1) {
    return (ntohl(v4.s_addr) >> 24) == 127;  // 127.0.0.0/8
  }
  in6_addr v6{};
  if (::inet_pton(AF_INET6, host.c_str(), &v6) == 1) {
    return IN6_IS_ADDR_LOOPBACK(&v6) != 0;
  }
  return false;  // a host name, "" (all interfaces) or garbage
}

std::optional<std::string> transport_warning(const DaemonConfig& config) {
  if ((config.token_file.empty() && config.users_file.empty()) || !config.tls_cert.empty()) {
    return std::nullopt;
  }
  if (is_loopback_listen_address(config.listen)) {
    if (config.http_listen.empty() || is_loopback_listen_address(config.http_listen)) {
      return std::nullopt;
    }
    return "serving the dashboard on " + config.http_listen +
           " with a bearer token but without TLS: the token crosses the network in clear text. "
           "Set tls-cert and tls-key, or put a TLS-terminating proxy in front and listen on "
           "loopback";
  }
  return "serving " + config.listen +
         " with a bearer token but without TLS: the token crosses the network in clear text. "
         "Set tls-cert and tls-key, or put a TLS-terminating proxy in front and listen on "
         "loopback";
}

std::optional<std::string> exposure_problem(const DaemonConfig& config) {
  if (!config.token_file.empty() || !config.users_file.empty() || config.insecure_no_auth) {
    return std::nullopt;
  }
  if (is_loopback_listen_address(config.listen)) {
    // The dashboard is the same service over HTTP: the same rule.
    if (config.http_listen.empty() || is_loopback_listen_address(config.http_listen)) {
      return std::nullopt;
    }
    return "refusing to serve the dashboard on " + config.http_listen +
           " without authentication: it is not a loopback address, so anyone who reaches it "
           "could cancel jobs and read every result. Set token-file or users-file, or "
           "insecure-no-auth if another layer authenticates";
  }
  return "refusing to listen on " + config.listen +
         " without authentication: it is not a loopback address, so anyone who reaches it "
         "could submit, cancel and delete jobs. Set token-file (--token-file, "
         "SOFTSHOCK_TOKEN_FILE) or users-file (--users-file, SOFTSHOCK_USERS_FILE), or "
         "insecure-no-auth if another layer authenticates";
}

}  // namespace softshock::server
