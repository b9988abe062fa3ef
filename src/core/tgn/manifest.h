// Model directory files other than the weights (manifest.yaml, loss.csv); no torch here.
#pragma once

#include <cstdint>
#include <string>

#include "ddace/tgn/sequence_model.h"

namespace ddace::tgn::files {

inline constexpr const char* kManifest = "manifest.yaml";
inline constexpr const char* kTask = "task.yaml";
inline constexpr const char* kWeights = "weights.pt";
inline constexpr const char* kLoss = "loss.csv";

/// FNV-1a 64 of a file's bytes; throws ddace::Error naming the file when unreadable.
uint64_t fileHash(const std::string& path);

/// manifest.yaml text. `weights_hash` and `weights_bytes` describe weights.pt.
std::string manifestText(const ModelInfo& info, const task::TaskSpec& spec, uint64_t weights_hash,
                         uint64_t weights_bytes);
/// Parses manifest.yaml against the task (entity names must match); fills everything in
/// `info` but the history. Throws ddace::Error naming `path` (with line and column).
ModelInfo parseManifest(const std::string& path, const task::TaskSpec& spec, uint64_t* weights_hash,
                        uint64_t* weights_bytes);

std::string lossCsvText(const std::vector<EpochRecord>& history);
/// Throws ddace::Error naming `path` and the line.
std::vector<EpochRecord> readLossCsv(const std::string& path);

/// Reads a whole file; throws ddace::Error naming it.
std::string readFile(const std::string& path);
/// Writes a whole file; throws ddace::Error naming it.
void writeFile(const std::string& path, const std::string& text);

}  // namespace ddace::tgn::files
