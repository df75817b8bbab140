// softshockd: the softshock simulation daemon (docs/api.md, docs/deploy.md). Settings come from
// flags, SOFTSHOCK_* variables and a config file (server/daemon_config.hpp). Exit codes: 0 after
// SIGTERM/SIGINT, 2 for an invalid setting, 1 when it cannot start.
#include <signal.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <iostream>
#include <stdexcept>
#include <string>

#include "server/daemon.hpp"
#include "server/daemon_config.hpp"
#include "server/log.hpp"
#include "softshock/version.hpp"

int main(int argc, char** argv) {
  using namespace softshock::server;
  LoadedConfig loaded;
  try {
    loaded = load_daemon_config(std::vector<std::string>(argv + 1, argv + argc),
                                [](const char* name) { return std::getenv(name); });
  } catch (const ConfigError& e) {
    std::cerr << "softshockd: " << e.what() << "\n(see softshockd --help)\n";
    return 2;
  }
  if (loaded.help) {
    std::cout << daemon_config_usage();
    return 0;
  }
  if (loaded.version) {
    std::cout << "softshockd " << SOFTSHOCK_VERSION << "\n";
    return 0;
  }
  const DaemonConfig& config = loaded.config;
  log_info(describe_daemon_config(loaded));
  if (config.insecure_no_auth && config.token_file.empty() && config.users_file.empty() &&
      !is_loopback_listen_address(config.listen)) {
    log_warning("insecure-no-auth: serving ", config.listen,
                " without authentication; anyone who reaches it can submit and delete jobs");
  }

  // Signals are taken synchronously by sigwait() below: block them before any thread exists so
  // every gRPC and worker thread inherits the mask and no handler runs in a random thread.
  sigset_t stop_signals;
  sigemptyset(&stop_signals);
  sigaddset(&stop_signals, SIGTERM);
  sigaddset(&stop_signals, SIGINT);
  sigaddset(&stop_signals, SIGHUP);  // reread the token and users files
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
  while (sigwait(&stop_signals, &received) == 0 && received == SIGHUP) {
    try {
      daemon->reload_users();
    } catch (const std::exception& e) {
      log_error("SIGHUP: users not reloaded: ", e.what());
    }
  }
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
