// softshock.v1.MeshService: meshes uploaded by remote clients (server/mesh_store.hpp), with the
// same bearer-token authentication as SimulationService.
#pragma once

#include "server/store/catalogue.hpp"
#include "server/store/mesh_store.hpp"
#include "server/transport/auth.hpp"
#include "softshock/v1/service.grpc.pb.h"

namespace softshock::server {

class MeshService final : public v1::MeshService::Service {
 public:
  MeshService(MeshStore& store, const Catalogue& catalogue, const Authenticator& auth)
      : store_(store), catalogue_(catalogue), auth_(auth) {}

  grpc::Status UploadMesh(grpc::ServerContext* ctx,
                          grpc::ServerReader<v1::UploadMeshRequest>* reader,
                          v1::Mesh* resp) override;
  grpc::Status ListMeshes(grpc::ServerContext* ctx, const v1::ListMeshesRequest* req,
                          v1::ListMeshesResponse* resp) override;
  grpc::Status DeleteMesh(grpc::ServerContext* ctx, const v1::DeleteMeshRequest* req,
                          v1::DeleteMeshResponse* resp) override;

 private:
  // The first QUEUED or RUNNING job whose spec names the mesh, if any.
  std::optional<std::string> job_using(const std::string& id) const;

  MeshStore& store_;
  const Catalogue& catalogue_;
  const Authenticator& auth_;
};

}  // namespace softshock::server
