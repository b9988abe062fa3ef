// SequenceModel::save and load: the model directory (weights here; manifest.yaml and
// loss.csv in manifest.cpp).
#include <torch/torch.h>

#include <filesystem>
#include <map>

#include "ddace/common/error.h"
#include "manifest.h"
#include "model_impl.h"

namespace ddace::tgn {

using torch::Tensor;

namespace fs = std::filesystem;

void SequenceModel::save(const std::string& model_dir) const {
  std::error_code ec;
  fs::create_directories(model_dir, ec);
  if (ec) throw Error(Diagnostic{model_dir, 0, 0, "cannot create the model directory: " + ec.message()});
  const std::string weights = (fs::path(model_dir) / files::kWeights).string();
  try {
    torch::serialize::OutputArchive archive;
    impl_->module().save(archive);
    archive.save_to(weights);
  } catch (const c10::Error& e) {
    throw Error(Diagnostic{weights, 0, 0, std::string("cannot write the weights: ") + e.what_without_backtrace()});
  }
  task::writeTaskYaml(impl_->spec, (fs::path(model_dir) / files::kTask).string());
  files::writeFile((fs::path(model_dir) / files::kLoss).string(), files::lossCsvText(impl_->info.history));
  files::writeFile((fs::path(model_dir) / files::kManifest).string(),
                   files::manifestText(impl_->info, impl_->spec, files::fileHash(weights), fs::file_size(weights)));
}

SequenceModel SequenceModel::load(const std::string& model_dir) {
  const fs::path dir(model_dir);
  if (!fs::is_directory(dir)) throw Error(Diagnostic{model_dir, 0, 0, "not a model directory (does not exist)"});
  auto impl = std::make_shared<Impl>();
  const std::string manifest = (dir / files::kManifest).string(), weights = (dir / files::kWeights).string();
  if (!fs::exists(manifest))
    throw Error(
        Diagnostic{manifest, 0, 0, "missing: " + model_dir + " is not a model directory (ddace train writes one)"});
  impl->spec = task::readTaskYaml((dir / files::kTask).string());
  uint64_t hash = 0, bytes = 0;
  impl->info = files::parseManifest(manifest, impl->spec, &hash, &bytes);
  impl->info.history = files::readLossCsv((dir / files::kLoss).string());
  std::error_code ec;
  const uint64_t size = fs::file_size(weights, ec);
  if (ec) throw Error(Diagnostic{weights, 0, 0, "cannot read the weights (missing?)"});
  if (size != bytes)
    throw Error(Diagnostic{
        weights, 0, 0,
        "truncated or replaced: " + std::to_string(size) + " bytes, the manifest says " + std::to_string(bytes)});
  if (files::fileHash(weights) != hash)
    throw Error(Diagnostic{weights, 0, 0, "corrupted: its checksum does not match " + manifest});
  impl->build();  // the loaded weights replace the initial ones
  // Module::load replaces tensors whatever their shape, so the shapes are checked here.
  std::vector<std::pair<std::string, std::vector<int64_t>>> expected;
  for (const auto& p : impl->module().named_parameters()) expected.emplace_back(p.key(), p.value().sizes().vec());
  for (const auto& b : impl->module().named_buffers()) expected.emplace_back(b.key(), b.value().sizes().vec());
  try {
    torch::serialize::InputArchive archive;
    archive.load_from(weights);
    impl->module().load(archive);
  } catch (const c10::Error& e) {
    throw Error(
        Diagnostic{weights, 0, 0, std::string("does not fit the manifest's network: ") + e.what_without_backtrace()});
  }
  std::map<std::string, std::vector<int64_t>> loaded;
  for (const auto& p : impl->module().named_parameters()) loaded[p.key()] = p.value().sizes().vec();
  for (const auto& b : impl->module().named_buffers()) loaded[b.key()] = b.value().sizes().vec();
  for (const auto& [name, shape] : expected)
    if (loaded[name] != shape)
      throw Error(Diagnostic{weights, 0, 0,
                             "does not fit the network of " + manifest + ": tensor '" + name + "' has another shape"});
  impl->module().eval();
  return SequenceModel(impl);
}

}  // namespace ddace::tgn
