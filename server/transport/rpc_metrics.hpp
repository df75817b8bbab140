// RPC metrics from a gRPC server interceptor: every call's service, method, type, status code and
// latency (from the call's start on a handler thread to its status), and for MeshService.UploadMesh
// the bytes received and whether the mesh was stored (server/metrics/daemon_metrics.hpp).
// Calls refused by the auth filter never reach interceptors: the Authenticator counts those.
// Method names come only from the services this binary knows (protobuf's generated descriptors);
// any other path is labelled "unknown", so a client cannot grow the label set.
#pragma once

#include <grpcpp/support/server_interceptor.h>

#include <memory>

#include "server/jobs/executor.hpp"
#include "server/metrics/daemon_metrics.hpp"
#include "server/transport/auth.hpp"
#include "server/transport/simulation_service.hpp"

namespace softshock::server {

// The factory for ServerBuilder::experimental().SetInterceptorCreators(); `metrics` outlives the
// server.
std::unique_ptr<grpc::experimental::ServerInterceptorFactoryInterface> rpc_metrics(
    DaemonMetrics& metrics);

// Gauges and counters read at scrape time from the transport and the executor: jobs waiting for
// and holding a worker (the executor's view), the configured workers, open streams, and calls the
// auth filter refused.
void add_service_gauges(DaemonMetrics& metrics, const Executor& executor,
                        const SimulationService& service, const Authenticator& auth, int workers);

}  // namespace softshock::server
