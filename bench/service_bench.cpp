// service_bench: latency of softshockd's API on loopback, as a client sees it.
//
//   service_bench [--server HOST:PORT | --daemon PATH] [--clients 8] [--submits 50]
//                 [--gets 500] [--rasters 30] [--raster 256x256] [--workers 1]
//
// Without --server it starts its own softshockd (the one built next to it, or --daemon) on
// 127.0.0.1:0 with a temporary data dir, and stops it at the end. Phases:
//   0. GetField (first, on an idle daemon): one client fetches a --raster raster of
//      mean_stress (16500-element baseline mesh, last frame) --rasters times;
//   1. SubmitJob: --clients threads, each on its own channel (its own TCP connection), submit
//      --submits tiny jobs each, all at once after a barrier;
//   2. GetJob: the same threads read --gets random jobs each.
// Prints median, p99 and max latency and the throughput of each phase. The submitted jobs
// run in the background on --workers runner threads (default 1), so the figures include a
// daemon that is also computing — as in use.
#include <fcntl.h>
#include <grpcpp/grpcpp.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <barrier>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "softshock/v1/service.grpc.pb.h"

#ifndef SOFTSHOCKD_PATH
#define SOFTSHOCKD_PATH "softshockd"
#endif

extern char** environ;

namespace {

namespace v1 = softshock::v1;
using Clock = std::chrono::steady_clock;

struct Options {
  std::string server, daemon = SOFTSHOCKD_PATH;
  int clients = 8, submits = 50, gets = 500, rasters = 30, workers = 1;
  int nx = 256, ny = 256;
};

[[noreturn]] void die(const std::string& message) {
  std::fprintf(stderr, "service_bench: %s\n", message.c_str());
  std::exit(1);
}

Options parse(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) die(a + " needs a value");
      return argv[++i];
    };
    if (a == "--server") {
      o.server = value();
    } else if (a == "--daemon") {
      o.daemon = value();
    } else if (a == "--clients") {
      o.clients = std::stoi(value());
    } else if (a == "--submits") {
      o.submits = std::stoi(value());
    } else if (a == "--gets") {
      o.gets = std::stoi(value());
    } else if (a == "--rasters") {
      o.rasters = std::stoi(value());
    } else if (a == "--workers") {
      o.workers = std::stoi(value());
    } else if (a == "--raster") {
      std::string r = value();
      auto x = r.find('x');
      if (x == std::string::npos) die("--raster NXxNY");
      o.nx = std::stoi(r.substr(0, x));
      o.ny = std::stoi(r.substr(x + 1));
    } else if (a == "--help" || a == "-h") {
      std::printf(
          "usage: service_bench [--server HOST:PORT | --daemon PATH] [--clients N] "
          "[--submits N] [--gets N] [--rasters N] [--raster NXxNY] [--workers N]\n");
      std::exit(0);
    } else {
      die("unknown option " + a);
    }
  }
  if (o.clients < 1 || o.submits < 1 || o.gets < 1 || o.rasters < 1) die("counts must be >= 1");
  return o;
}

// A softshockd child with its own data dir; SIGTERM on destruction.
class Daemon {
 public:
  Daemon(const std::string& exe, int workers) {
    char tmpl[] = "/tmp/service-bench-XXXXXX";
    if (mkdtemp(tmpl) == nullptr) die("mkdtemp failed");
    dir_ = tmpl;
    const std::string port_file = dir_ + "/port";
    std::vector<std::string> args = {exe,        "--data-dir",  dir_ + "/data",
                                     "--listen", "127.0.0.1:0", "--port-file",
                                     port_file,  "--workers",   std::to_string(workers)};
    std::vector<char*> argv;
    for (auto& s : args) argv.push_back(s.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    // The daemon logs every job; keep that out of the figures.
    posix_spawn_file_actions_addopen(&fa, STDERR_FILENO, (dir_ + "/softshockd.log").c_str(),
                                     O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_adddup2(&fa, STDERR_FILENO, STDOUT_FILENO);
    int rc = posix_spawn(&pid_, exe.c_str(), &fa, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&fa);
    if (rc != 0) die("cannot start " + exe + " (pass --daemon PATH or --server)");
    for (int i = 0; i < 600; ++i) {
      std::ifstream f(port_file);
      std::string text;
      if (f >> text && !text.empty()) {
        address_ = "127.0.0.1:" + text.substr(text.rfind(':') + 1);
        return;
      }
      int status = 0;
      if (waitpid(pid_, &status, WNOHANG) == pid_) die("softshockd exited at start-up");
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    die("softshockd wrote no port file");
  }
  ~Daemon() {
    kill(pid_, SIGTERM);
    int status = 0;
    waitpid(pid_, &status, 0);
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }
  const std::string& address() const { return address_; }

 private:
  pid_t pid_ = 0;
  std::string dir_, address_;
};

std::shared_ptr<grpc::Channel> make_channel(const std::string& address) {
  grpc::ChannelArguments args;
  // Each benchmark client gets its own connection, as separate processes would.
  args.SetInt(GRPC_ARG_USE_LOCAL_SUBCHANNEL_POOL, 1);
  args.SetMaxReceiveMessageSize(64 << 20);
  return grpc::CreateCustomChannel(address, grpc::InsecureChannelCredentials(), args);
}

void set_deadline(grpc::ClientContext& ctx) {
  ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(60));
}

v1::RunSpec tiny_spec() {
  v1::RunSpec s;
  s.mutable_geometry()->mutable_disk()->set_radius(9e-5);
  s.mutable_geometry()->set_target_elements(300);
  s.mutable_run()->set_end_time(1e-8);
  s.mutable_run()->set_output_interval(5e-9);
  return s;
}

v1::Job wait_done(v1::SimulationService::Stub& stub, const std::string& id) {
  for (;;) {
    grpc::ClientContext ctx;
    set_deadline(ctx);
    v1::GetJobRequest req;
    req.set_id(id);
    v1::Job job;
    auto st = stub.GetJob(&ctx, req, &job);
    if (!st.ok()) die("GetJob: " + st.error_message());
    if (job.state() == v1::SUCCEEDED) return job;
    if (job.state() == v1::FAILED || job.state() == v1::CANCELLED) die("job " + id + " failed");
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
}

struct Stats {
  double median_ms, p99_ms, max_ms;
};

Stats stats(std::vector<double> seconds) {
  std::sort(seconds.begin(), seconds.end());
  auto at = [&](double q) {
    // Nearest-rank percentile: no interpolation between samples that were never measured.
    std::size_t k = static_cast<std::size_t>(std::ceil(q * seconds.size()));
    return seconds[std::clamp<std::size_t>(k, 1, seconds.size()) - 1] * 1e3;
  };
  return {at(0.5), at(0.99), seconds.back() * 1e3};
}

void report(const char* name, const std::vector<double>& lat, double wall_s, const char* extra) {
  Stats s = stats(lat);
  std::printf("%-22s %7zu  %9.3f  %9.3f  %9.3f  %10.0f%s%s\n", name, lat.size(), s.median_ms,
              s.p99_ms, s.max_ms, lat.size() / wall_s, *extra ? "  " : "", extra);
}

}  // namespace

int main(int argc, char** argv) {
  Options o = parse(argc, argv);
  std::unique_ptr<Daemon> daemon;
  std::string address = o.server;
  if (address.empty()) {
    daemon = std::make_unique<Daemon>(o.daemon, o.workers);
    address = daemon->address();
  }
  auto control_channel = make_channel(address);
  auto control = v1::SimulationService::NewStub(control_channel);
  if (!control_channel->WaitForConnected(std::chrono::system_clock::now() +
                                         std::chrono::seconds(30))) {
    die("cannot connect to " + address);
  }

  // The raster job first, so it is finished (and the queue empty) before the timed phases.
  std::string raster_job;
  {
    v1::SubmitJobRequest req;
    req.mutable_spec()->mutable_geometry()->mutable_disk()->set_radius(9e-5);
    req.mutable_spec()->mutable_geometry()->set_target_elements(16500);  // the baseline mesh
    req.mutable_spec()->mutable_run()->set_end_time(2e-8);
    req.mutable_spec()->mutable_run()->set_output_interval(1e-8);
    (*req.mutable_labels())["bench"] = "raster";
    grpc::ClientContext ctx;
    set_deadline(ctx);
    v1::Job job;
    auto st = control->SubmitJob(&ctx, req, &job);
    if (!st.ok()) die("SubmitJob: " + st.error_message());
    raster_job = wait_done(*control, job.id()).id();
  }

  std::printf("service_bench: softshockd at %s, %d clients (own connections), %u CPUs%s\n",
              address.c_str(), o.clients, std::thread::hardware_concurrency(),
              daemon ? (", daemon workers " + std::to_string(o.workers)).c_str() : "");
  std::printf("%-22s %7s  %9s  %9s  %9s  %10s\n", "operation", "calls", "median ms", "p99 ms",
              "max ms", "calls/s");

  // Field raster first, on an idle daemon (no queued jobs competing for the CPUs): one client,
  // sequential, the whole stream counted (header + chunks).
  // One extra call first, untimed: it pays for opening the result file and whatever the
  // daemon caches per job, which is not the steady state being measured.
  std::vector<double> raster_lat;
  std::size_t values = 0;
  auto r0 = Clock::now();
  for (int i = -1; i < o.rasters; ++i) {
    if (i == 0) r0 = Clock::now();
    v1::GetFieldRequest req;
    req.set_id(raster_job);
    req.set_name("mean_stress");
    req.mutable_raster()->set_nx(o.nx);
    req.mutable_raster()->set_ny(o.ny);
    grpc::ClientContext ctx;
    set_deadline(ctx);
    auto start = Clock::now();
    auto reader = control->GetField(&ctx, req);
    v1::FieldChunk chunk;
    values = 0;
    while (reader->Read(&chunk)) values += static_cast<std::size_t>(chunk.values_size());
    auto st = reader->Finish();
    if (i >= 0) raster_lat.push_back(std::chrono::duration<double>(Clock::now() - start).count());
    if (!st.ok()) die("GetField: " + st.error_message());
  }
  char extra[128];
  std::snprintf(
      extra, sizeof extra, "%dx%d, %zu values, %.1f MB/s", o.nx, o.ny, values,
      values * 8.0 * o.rasters / 1e6 / std::chrono::duration<double>(Clock::now() - r0).count());
  report("GetField raster", raster_lat, std::chrono::duration<double>(Clock::now() - r0).count(),
         extra);

  std::vector<std::vector<double>> submit_lat(o.clients), get_lat(o.clients);
  std::vector<std::vector<std::string>> ids(o.clients);
  std::vector<std::unique_ptr<v1::SimulationService::Stub>> stubs;
  std::vector<std::shared_ptr<grpc::Channel>> channels;
  for (int c = 0; c < o.clients; ++c) {
    channels.push_back(make_channel(address));
    stubs.push_back(v1::SimulationService::NewStub(channels.back()));
  }
  std::atomic<bool> failed{false};
  std::barrier sync(o.clients + 1);
  Clock::time_point t0, t1, t2;
  std::vector<std::thread> threads;
  for (int c = 0; c < o.clients; ++c) {
    threads.emplace_back([&, c] {
      auto& stub = *stubs[c];
      // Warm-up: connect and run a few calls before the clock starts.
      for (int i = 0; i < 5; ++i) {
        grpc::ClientContext ctx;
        set_deadline(ctx);
        v1::GetJobRequest req;
        req.set_id(raster_job);
        v1::Job job;
        if (!stub.GetJob(&ctx, req, &job).ok()) failed = true;
      }
      const v1::RunSpec spec = tiny_spec();
      sync.arrive_and_wait();
      for (int i = 0; i < o.submits; ++i) {
        v1::SubmitJobRequest req;
        *req.mutable_spec() = spec;
        (*req.mutable_labels())["bench"] = "submit";
        req.set_request_id("bench-" + std::to_string(c) + "-" + std::to_string(i) + "-" +
                           std::to_string(getpid()));
        grpc::ClientContext ctx;
        set_deadline(ctx);
        v1::Job job;
        auto start = Clock::now();
        auto st = stub.SubmitJob(&ctx, req, &job);
        submit_lat[c].push_back(std::chrono::duration<double>(Clock::now() - start).count());
        if (!st.ok()) {
          std::fprintf(stderr, "SubmitJob: %s\n", st.error_message().c_str());
          failed = true;
          break;
        }
        ids[c].push_back(job.id());
      }
      sync.arrive_and_wait();  // end of the submit phase
      sync.arrive_and_wait();  // start of the get phase (ids of every client are known)
      std::mt19937 rng(static_cast<unsigned>(c));
      for (int i = 0; i < o.gets; ++i) {
        const auto& pool = ids[static_cast<std::size_t>(rng() % o.clients)];
        v1::GetJobRequest req;
        req.set_id(pool.empty() ? raster_job : pool[rng() % pool.size()]);
        grpc::ClientContext ctx;
        set_deadline(ctx);
        v1::Job job;
        auto start = Clock::now();
        auto st = stub.GetJob(&ctx, req, &job);
        get_lat[c].push_back(std::chrono::duration<double>(Clock::now() - start).count());
        if (!st.ok()) failed = true;
      }
      sync.arrive_and_wait();
    });
  }
  sync.arrive_and_wait();
  t0 = Clock::now();
  sync.arrive_and_wait();
  t1 = Clock::now();
  sync.arrive_and_wait();
  auto tg = Clock::now();
  sync.arrive_and_wait();
  t2 = Clock::now();
  for (auto& t : threads) t.join();
  if (failed) die("some calls failed");

  std::vector<double> all_submit, all_get;
  for (auto& v : submit_lat) all_submit.insert(all_submit.end(), v.begin(), v.end());
  for (auto& v : get_lat) all_get.insert(all_get.end(), v.begin(), v.end());
  report("SubmitJob", all_submit, std::chrono::duration<double>(t1 - t0).count(), "");
  report("GetJob", all_get, std::chrono::duration<double>(t2 - tg).count(), "");

  // Leave nothing running in a daemon we did not start.
  if (!daemon) {
    for (const auto& v : ids) {
      for (const auto& id : v) {
        grpc::ClientContext ctx;
        set_deadline(ctx);
        v1::CancelJobRequest req;
        req.set_id(id);
        v1::Job job;
        control->CancelJob(&ctx, req, &job);  // finished ones answer FAILED_PRECONDITION
      }
    }
  }
  return 0;
}
