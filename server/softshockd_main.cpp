// softshockd: the softshock simulation daemon (docs/api.md). Flags, signals, exit codes:
// 0 after SIGTERM/SIGINT, 2 for bad flags, 1 when it cannot start.
#include <signal.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <iostream>
#include <map>
#include <stdexcept>
#include <string>

#include "server/daemon.hpp"
#include "server/log.hpp"

namespace {

constexpr const char* kUsage = R"(usage: softshockd [flags]

Runs softshock simulations submitted over gRPC (softshock.v1.SimulationService).

  --data-dir DIR           catalogue and results (default ./data; created if missing)
  --listen ADDR            address to serve on (default 127.0.0.1:50051; 127.0.0.1:0 = any port)
  --port-file FILE         write the bound port number here once listening
  --workers N              jobs run at once (default: hardware threads)
  --max-queued N           waiting jobs before SubmitJob answers RESOURCE_EXHAUSTED (default 1000)
  --token-file FILE        require 'authorization: Bearer <token>' with the token in FILE
  --tls-cert FILE          PEM certificate chain (with --tls-key: serve TLS)
  --tls-key FILE           PEM private key
  --max-elements N         largest mesh a job may use (default 2000000)
  --max-end-time SECONDS   longest simulated end time (default 1e-5)
  --max-wall-time SECONDS  wall-clock limit per job, 0 = none (default 0)
  --solver-threads N       element-loop threads per job (default 1)
  --max-attempts N         runs a job gets when the daemon is killed under it (default 3)
  --help                   this text
  --version                print the version
)";

[[noreturn]] void usage_error(const std::string& message) {
  std::cerr << "softshockd: " << message << "\n(see softshockd --help)\n";
  std::exit(2);
}

long long parse_int(const std::string& flag, const std::string& v, long long lo, long long hi) {
  try {
    std::size_t used = 0;
    const long long x = std::stoll(v, &used);
    if (used != v.size() || x < lo || x > hi) throw std::out_of_range(v);
    return x;
  } catch (const std::exception&) {
    usage_error(flag + " expects an integer in " + std::to_string(lo) + ".." + std::to_string(hi) +
                ", got '" + v + "'");
  }
}

double parse_double(const std::string& flag, const std::string& v, double lo) {
  try {
    std::size_t used = 0;
    const double x = std::stod(v, &used);
    if (used != v.size() || !(x >= lo) || x > 1e300) throw std::out_of_range(v);
    return x;
  } catch (const std::exception&) {
    usage_error(flag + " expects a number >= " + std::to_string(lo) + ", got '" + v + "'");
  }
}

softshock::server::DaemonConfig parse_flags(int argc, char** argv) {
  softshock::server::DaemonConfig c;
  for (int i = 1; i < argc; ++i) {
    std::string arg = argv[i];
    if (arg == "--help" || arg == "-h") {
      std::cout << kUsage;
      std::exit(0);
    }
    if (arg == "--version") {
      std::cout << "softshockd " << SOFTSHOCK_VERSION << "\n";
      std::exit(0);
    }
    if (arg.rfind("--", 0) != 0) usage_error("unexpected argument '" + arg + "'");
    std::string value;
    if (auto eq = arg.find('='); eq != std::string::npos) {
      value = arg.substr(eq + 1);
      arg = arg.substr(0, eq);
    } else {
      if (i + 1 >= argc) usage_error(arg + " needs a value");
      value = argv[++i];
    }
    if (arg == "--data-dir") {
      c.data_dir = value;
    } else if (arg == "--listen") {
      c.listen = value;
    } else if (arg == "--port-file") {
      c.port_file = value;
    } else if (arg == "--workers") {
      c.workers = static_cast<int>(parse_int(arg, value, 1, 4096));
    } else if (arg == "--max-queued") {
      c.max_queued = static_cast<std::size_t>(parse_int(arg, value, 1, 100'000'000));
    } else if (arg == "--token-file") {
      c.token_file = value;
    } else if (arg == "--tls-cert") {
      c.tls_cert = value;
    } else if (arg == "--tls-key") {
      c.tls_key = value;
    } else if (arg == "--max-elements") {
      c.max_elements = static_cast<int>(parse_int(arg, value, 1, 2'000'000'000));
    } else if (arg == "--max-end-time") {
      c.max_end_time_s = parse_double(arg, value, 0);
    } else if (arg == "--max-wall-time") {
      c.max_wall_time_s = parse_double(arg, value, 0);
    } else if (arg == "--solver-threads") {
      c.solver_threads = static_cast<int>(parse_int(arg, value, 1, 1024));
    } else if (arg == "--max-attempts") {
      c.max_attempts = static_cast<int>(parse_int(arg, value, 1, 1000));
    } else {
      usage_error("unknown flag " + arg);
    }
  }
  if (c.tls_cert.empty() != c.tls_key.empty()) usage_error("--tls-cert and --tls-key go together");
  return c;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace softshock::server;
  const DaemonConfig config = parse_flags(argc, argv);

  // Signals are taken synchronously by sigwait() below: block them before any thread exists so
  // every gRPC and worker thread inherits the mask and no handler runs in a random thread.
  sigset_t stop_signals;
  sigemptyset(&stop_signals);
  sigaddset(&stop_signals, SIGTERM);
  sigaddset(&stop_signals, SIGINT);
  pthread_sigmask(SIG_BLOCK, &stop_signals, nullptr);
  signal(SIGPIPE, SIG_IGN);

  std::unique_ptr<Daemon> daemon;
  try {
    daemon = std::make_unique<Daemon>(config);
    daemon->start();
  } catch (const std::exception& e) {
    log_error("cannot start: ", e.what());
    return 1;
  }

  int received = 0;
  sigwait(&stop_signals, &received);
  log_info("received ", strsignal(received));
  bool clean = false;
  try {
    clean = daemon->stop();
  } catch (const std::exception& e) {
    log_error("during shutdown: ", e.what());
  }
  if (!clean) {
    // A worker is still inside a phase that cannot be interrupted; its job is already recorded
    // as QUEUED. Leave without running destructors that would wait for it.
    std::_Exit(0);
  }
  daemon.reset();
  return 0;
}
