// Model directory files other than the weights (manifest.yaml, loss.csv); no torch here.
#pragma once

#include <cstdint>
#include <map>
#include <string>

#include "ddace/common/file.h"
#include "ddace/tgn/sequence_model.h"

namespace ddace::tgn::files {

inline constexpr const char* kManifest = "manifest.yaml";
inline constexpr const char* kTask = "task.yaml";
inline constexpr const char* kWeights = "weights.pt";
inline constexpr const char* kLoss = "loss.csv";
/// The manifest's last line: "manifest_sha256: <SHA-256 of every byte before this line>".
inline constexpr const char* kManifestDigestKey = "manifest_sha256";
/// Largest weights.pt read (the largest network the hyper-parameter bounds allow is far
/// below; a bigger file is not a model's).
inline constexpr uint64_t kMaxWeightsBytes = uint64_t{1} << 30;

/// Size and SHA-256 of bytes.
FileDigest digestOf(const std::string& bytes);
/// Throws ddace::Error naming `path` (and `manifest`) when `bytes` do not have the size
/// and digest `expected` records.
void verifyDigest(const std::string& path, const std::string& bytes, const FileDigest& expected,
                  const std::string& manifest);

/// manifest.yaml text, ending with its own digest line. `files` are the digests of the
/// model directory's files by name (at least task.yaml, weights.pt, loss.csv).
std::string manifestText(const ModelInfo& info, const task::TaskSpec& spec,
                         const std::map<std::string, FileDigest>& files);
/// Parses manifest.yaml text against the task (entities must match): checks the format
/// (an older one is refused with "retrain"), then the manifest's own digest, then every
/// field and its range. Fills everything in `info` but the history (`info.files` too).
/// Throws ddace::Error naming `path` (with line and column).
ModelInfo parseManifest(const std::string& text, const std::string& path, const task::TaskSpec& spec);
/// The manifest's `task` and `files` without checking them against a task.yaml (to read
/// task.yaml's digest before task.yaml). Same format and digest checks as parseManifest.
std::map<std::string, FileDigest> manifestFiles(const std::string& text, const std::string& path);

std::string lossCsvText(const std::vector<EpochRecord>& history);
/// Parses loss.csv text; throws ddace::Error naming `path` and the line.
std::vector<EpochRecord> parseLossCsv(const std::string& text, const std::string& path);
/// Reads and parses `path` (bounded, regular files only).
std::vector<EpochRecord> readLossCsv(const std::string& path);

/// Reads a whole regular file (bounded, common/file.h); throws ddace::Error naming it.
std::string readFile(const std::string& path, uint64_t max_bytes = kMaxInputFileBytes);
/// Writes a whole file (checked, atomic); throws ddace::Error naming it.
void writeFile(const std::string& path, const std::string& text);

}  // namespace ddace::tgn::files
