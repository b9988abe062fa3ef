// SequenceModel::save and load: the model directory (weights here; manifest.yaml and
// loss.csv in manifest.cpp).
#include <torch/torch.h>

#include <filesystem>
#include <map>
#include <sstream>

#include "ddace/common/error.h"
#include "manifest.h"
#include "model_impl.h"

namespace ddace::tgn {

using torch::Tensor;

namespace fs = std::filesystem;

void SequenceModel::save(const std::string& model_dir, const std::vector<std::string>& bound_files) const {
  if (impl_->bound)
    throw Error(Diagnostic{model_dir, 0, 0, "a model bound to another task's entities is not saved (its own is)"});
  std::error_code ec;
  fs::create_directories(model_dir, ec);
  if (ec) throw Error(Diagnostic{model_dir, 0, 0, "cannot create the model directory: " + ec.message()});
  const fs::path dir(model_dir);
  std::ostringstream weights;
  try {
    torch::serialize::OutputArchive archive;
    impl_->module().save(archive);
    // An ensemble's other members, each an archive of its own (member1, member2, ...).
    for (size_t k = 0; k < impl_->others.size(); ++k) {
      torch::serialize::OutputArchive member;
      impl_->others[k]->save(member);
      archive.write("member" + std::to_string(k + 1), member);
    }
    archive.save_to(weights);
  } catch (const c10::Error& e) {
    throw Error(Diagnostic{(dir / files::kWeights).string(), 0, 0,
                           std::string("cannot serialise the weights: ") + e.what_without_backtrace()});
  }
  // The digests are of the bytes written, so nothing is read back before the manifest.
  std::map<std::string, FileDigest> digests;
  const auto put = [&](const char* name, const std::string& bytes) {
    files::writeFile((dir / name).string(), bytes);
    digests[name] = files::digestOf(bytes);
  };
  put(files::kWeights, weights.str());
  put(files::kTask, task::taskYamlText(impl_->spec));
  put(files::kLoss, files::lossCsvText(impl_->info.history));
  for (const auto& name : bound_files) digests[name] = files::digestOf(files::readFile((dir / name).string()));
  files::writeFile((dir / files::kManifest).string(), files::manifestText(impl_->info, impl_->spec, digests));
}

SequenceModel SequenceModel::load(const std::string& model_dir) {
  const fs::path dir(model_dir);
  if (!fs::is_directory(dir)) throw Error(Diagnostic{model_dir, 0, 0, "not a model directory (does not exist)"});
  auto impl = std::make_shared<Impl>();
  const std::string manifest = (dir / files::kManifest).string(), weights = (dir / files::kWeights).string();
  if (!fs::exists(manifest))
    throw Error(
        Diagnostic{manifest, 0, 0, "missing: " + model_dir + " is not a model directory (ddace train writes one)"});
  // Every file is read once, checked against the manifest, and parsed from those bytes.
  const std::string manifest_text = files::readFile(manifest);
  const std::map<std::string, FileDigest> digests = files::manifestFiles(manifest_text, manifest);
  const auto verified = [&](const char* name, uint64_t max_bytes) {
    const std::string path = (dir / name).string();
    const std::string bytes = files::readFile(path, max_bytes);
    files::verifyDigest(path, bytes, digests.at(name), manifest);
    return bytes;
  };
  const std::string task_path = (dir / files::kTask).string();
  impl->spec = task::parseTaskYaml(verified(files::kTask, kMaxInputFileBytes), task_path);
  impl->info = files::parseManifest(manifest_text, manifest, impl->spec);
  impl->info.history = files::parseLossCsv(verified(files::kLoss, kMaxInputFileBytes), (dir / files::kLoss).string());
  if (static_cast<int>(impl->info.history.size()) > impl->info.options.max_epochs)
    throw Error(Diagnostic{(dir / files::kLoss).string(), 0, 0, "more epochs than the manifest's max_epochs"});
  const std::string weight_bytes = verified(files::kWeights, files::kMaxWeightsBytes);
  impl->build(impl->info.plan.ensemble);  // the loaded weights replace the initial ones
  // Module::load replaces tensors whatever their shape, so the shapes are checked here.
  std::vector<torch::nn::Module*> modules = {&impl->module()};
  for (SceneNetwork& o : impl->others) modules.push_back(o.get());
  const auto shapes = [&] {
    std::vector<std::pair<std::string, std::vector<int64_t>>> out;
    for (size_t k = 0; k < modules.size(); ++k) {
      const std::string prefix = k == 0 ? "" : "member" + std::to_string(k) + ".";
      for (const auto& p : modules[k]->named_parameters()) out.emplace_back(prefix + p.key(), p.value().sizes().vec());
      for (const auto& b : modules[k]->named_buffers()) out.emplace_back(prefix + b.key(), b.value().sizes().vec());
    }
    return out;
  };
  const auto expected = shapes();
  try {
    torch::serialize::InputArchive archive;
    archive.load_from(weight_bytes.data(), weight_bytes.size());
    impl->module().load(archive);
    for (size_t k = 0; k < impl->others.size(); ++k) {
      torch::serialize::InputArchive member;
      if (!archive.try_read("member" + std::to_string(k + 1), member))
        throw Error(Diagnostic{weights, 0, 0,
                               "does not fit the manifest's network: no weights of the ensemble's member " +
                                   std::to_string(k + 1) + " (plan: ensemble " +
                                   std::to_string(impl->others.size() + 1) + ")"});
      impl->others[k]->load(member);
    }
    torch::serialize::InputArchive extra;
    if (archive.try_read("member" + std::to_string(impl->others.size() + 1), extra))
      throw Error(Diagnostic{weights, 0, 0,
                             "does not fit the manifest's network: it holds more networks than the plan's ensemble " +
                                 std::to_string(impl->others.size() + 1)});
  } catch (const c10::Error& e) {
    throw Error(
        Diagnostic{weights, 0, 0, std::string("does not fit the manifest's network: ") + e.what_without_backtrace()});
  }
  std::map<std::string, std::vector<int64_t>> loaded;
  for (const auto& [name, shape] : shapes()) loaded[name] = shape;
  for (const auto& [name, shape] : expected)
    if (loaded[name] != shape)
      throw Error(Diagnostic{weights, 0, 0,
                             "does not fit the network of " + manifest + ": tensor '" + name + "' has another shape"});
  for (torch::nn::Module* m : modules) m->eval();
  return SequenceModel(impl);
}

}  // namespace ddace::tgn
