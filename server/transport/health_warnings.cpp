#include "server/transport/health_warnings.hpp"

#include <string_view>

namespace softshock::server {
namespace {

namespace gx = grpc::experimental;

constexpr std::string_view kHealthMethods = "/grpc.health.v1.Health/";

// A metadata value must be printable ASCII, or gRPC drops the call's metadata.
std::string printable(std::string text) {
  for (char& c : text) {
    if (c < 0x20 || c > 0x7e) c = '?';
  }
  return text;
}

class HealthWarningsInterceptor : public gx::Interceptor {
 public:
  explicit HealthWarningsInterceptor(const std::vector<std::string>& warnings)
      : warnings_(warnings) {}
  void Intercept(gx::InterceptorBatchMethods* methods) override {
    if (methods->QueryInterceptionHookPoint(
            gx::InterceptionHookPoints::PRE_SEND_INITIAL_METADATA)) {
      if (auto* metadata = methods->GetSendInitialMetadata()) {
        for (const auto& w : warnings_) metadata->emplace(kHealthWarningKey, w);
      }
    }
    methods->Proceed();
  }

 private:
  const std::vector<std::string>& warnings_;  // owned by the factory, which outlives the server
};

class HealthWarningsFactory : public gx::ServerInterceptorFactoryInterface {
 public:
  explicit HealthWarningsFactory(std::vector<std::string> warnings) {
    for (auto& w : warnings) warnings_.push_back(printable(std::move(w)));
  }
  gx::Interceptor* CreateServerInterceptor(gx::ServerRpcInfo* info) override {
    const char* method = info->method();
    if (method == nullptr ||
        std::string_view(method).substr(0, kHealthMethods.size()) != kHealthMethods) {
      return nullptr;
    }
    return new HealthWarningsInterceptor(warnings_);
  }

 private:
  std::vector<std::string> warnings_;
};

}  // namespace

std::unique_ptr<gx::ServerInterceptorFactoryInterface> health_warnings(
    std::vector<std::string> warnings) {
  return std::make_unique<HealthWarningsFactory>(std::move(warnings));
}

}  // namespace softshock::server
