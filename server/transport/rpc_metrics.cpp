#include "server/transport/rpc_metrics.hpp"

#include <google/protobuf/descriptor.h>

#include <chrono>
#include <mutex>
#include <string>
#include <string_view>
#include <unordered_map>
#include <utility>

#include "server/transport/rpc_guard.hpp"
#include "softshock/v1/service.pb.h"

namespace softshock::server {
namespace {

namespace gx = grpc::experimental;
using Clock = std::chrono::steady_clock;

constexpr std::string_view kUploadMesh = "/softshock.v1.MeshService/UploadMesh";

const char* type_name(gx::ServerRpcInfo::Type type) {
  switch (type) {
    case gx::ServerRpcInfo::Type::UNARY:
      return "unary";
    case gx::ServerRpcInfo::Type::CLIENT_STREAMING:
      return "client_stream";
    case gx::ServerRpcInfo::Type::SERVER_STREAMING:
      return "server_stream";
    case gx::ServerRpcInfo::Type::BIDI_STREAMING:
      return "bidi_stream";
  }
  return "unknown";
}

class RpcMetricsInterceptor : public gx::Interceptor {
 public:
  RpcMetricsInterceptor(DaemonMetrics& metrics, std::string service, std::string method,
                        const char* type, bool upload)
      : metrics_(metrics),
        service_(std::move(service)),
        method_(std::move(method)),
        type_(type),
        upload_(upload),
        start_(Clock::now()) {}

  void Intercept(gx::InterceptorBatchMethods* methods) override {
    if (upload_ &&
        methods->QueryInterceptionHookPoint(gx::InterceptionHookPoints::POST_RECV_MESSAGE)) {
      if (const auto* m = static_cast<const v1::UploadMeshRequest*>(methods->GetRecvMessage())) {
        bytes_ += m->data().size();
      }
    }
    if (methods->QueryInterceptionHookPoint(gx::InterceptionHookPoints::PRE_SEND_STATUS)) {
      const grpc::Status status = methods->GetSendStatus();
      const double seconds = std::chrono::duration<double>(Clock::now() - start_).count();
      metrics_.rpc_handled(service_, method_, type_, rpc::status_code_name(status.error_code()),
                           seconds);
      if (upload_) metrics_.mesh_upload(status.ok(), bytes_);
    }
    methods->Proceed();
  }

 private:
  DaemonMetrics& metrics_;
  const std::string service_, method_;
  const char* type_;
  const bool upload_;
  const Clock::time_point start_;
  std::uint64_t bytes_ = 0;
};

class RpcMetricsFactory : public gx::ServerInterceptorFactoryInterface {
 public:
  explicit RpcMetricsFactory(DaemonMetrics& metrics) : metrics_(metrics) {}

  gx::Interceptor* CreateServerInterceptor(gx::ServerRpcInfo* info) override {
    const std::string_view path = info->method() == nullptr ? "" : info->method();
    const auto [service, method] = known(path);
    return new RpcMetricsInterceptor(metrics_, service, method, type_name(info->type()),
                                     path == kUploadMesh);
  }

 private:
  // ("softshock.v1.SimulationService", "GetJob") for a method this binary has descriptors of,
  // ("unknown", "unknown") for anything else.
  std::pair<std::string, std::string> known(std::string_view path) {
    std::lock_guard lock(mutex_);
    if (auto it = cache_.find(std::string(path)); it != cache_.end()) return it->second;
    const auto slash = path.rfind('/');
    if (path.size() > 1 && path[0] == '/' && slash != std::string_view::npos && slash > 1) {
      const std::string service(path.substr(1, slash - 1));
      const std::string method(path.substr(slash + 1));
      const auto* pool = google::protobuf::DescriptorPool::generated_pool();
      if (pool->FindMethodByName(service + "." + method) != nullptr) {
        return cache_.emplace(std::string(path), std::make_pair(service, method)).first->second;
      }
    }
    return {"unknown", "unknown"};
  }

  DaemonMetrics& metrics_;
  std::mutex mutex_;
  std::unordered_map<std::string, std::pair<std::string, std::string>> cache_;  // known only
};

}  // namespace

std::unique_ptr<gx::ServerInterceptorFactoryInterface> rpc_metrics(DaemonMetrics& metrics) {
  return std::make_unique<RpcMetricsFactory>(metrics);
}

void add_service_gauges(DaemonMetrics& metrics, const Executor& executor,
                        const SimulationService& service, const Authenticator& auth, int workers) {
  using metrics::Sample;
  using metrics::Type;
  auto& r = metrics.registry();
  r.sampled(Type::kGauge, "softshock_executor_queued",
            "Jobs waiting in the executor's queue for a worker.", {}, [&executor] {
              return std::vector<Sample>{{{}, static_cast<double>(executor.queued())}};
            });
  r.sampled(Type::kGauge, "softshock_executor_running", "Jobs the executor is running now.", {},
            [&executor] {
              return std::vector<Sample>{{{}, static_cast<double>(executor.running())}};
            });
  r.sampled(Type::kGauge, "softshock_workers", "Jobs the daemon runs at once (--workers).", {},
            [workers] {
              return std::vector<Sample>{{{}, static_cast<double>(workers)}};
            });
  r.sampled(Type::kGauge, "softshock_active_streams",
            "Open WatchJob and GetField streams (bounded by the daemon's stream pool).", {},
            [&service] {
              return std::vector<Sample>{{{}, static_cast<double>(service.active_streams())}};
            });
  r.sampled(Type::kCounter, "softshock_auth_refused_total",
            "Calls refused for want of a valid bearer token (they reach no handler).", {}, [&auth] {
              return std::vector<Sample>{{{}, static_cast<double>(auth.refused())}};
            });
}

}  // namespace softshock::server
