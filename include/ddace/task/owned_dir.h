// Output directories that a tool owns as a whole (`ddace generate --out DIR`, `ddace train
// --out MODELDIR`, a task directory written by writeTaskDir): written so that nothing a
// user put there is lost.
//
// The directory gets a manifest, kOwnedManifest (the ownership record), naming the tool
// and listing every file it wrote, one line each, sorted by path:
//   # ddace generate wrote these files (SHA-256, bytes, path); it replaces only these
//   <64 hex digits> <bytes> <path relative to the directory, '/'-separated>
// Records written before SHA-256 name "FNV-1a 64" in the header and hold 16 hex
// digits; they are still read (so --force replaces such an output), never written.
// Writing again:
//   - an empty or missing directory is written;
//   - a directory holding anything else is refused, naming what is there, unless
//     `replace` is set and everything in it is this tool's own: listed in a manifest of
//     the same tool and unchanged since, or byte-identical to the file about to be
//     written in its place (so replacing it loses nothing). Another tool's output
//     (generate's data under train) is somebody else's;
//   - the new content is written into a temporary sibling directory, every file
//     flushed, synced and checked, and only then swapped in for the old directory in
//     one rename (renameat2 RENAME_EXCHANGE); a failed run leaves the old directory as
//     it was, and no file of the old output survives in the new one. A run killed on
//     the way leaves its temporary sibling (".NAME.tmp-PID-N", marked incomplete); the
//     next write of the same directory removes it.
#pragma once

#include <functional>
#include <string>
#include <utility>
#include <vector>

namespace ddace::task {

inline constexpr const char* kOwnedManifest = "ddace-output.txt";

/// A file to write: path relative to the directory ("train/demos/demo_000.csv"), bytes.
using OwnedFile = std::pair<std::string, std::string>;

/// Writes `files` as the whole content of directory `dir` (plus the manifest), as
/// above. `tool` names the writer in messages and in the manifest ("ddace generate").
/// Throws ddace::Error naming `dir` and what is in the way, or the file that could not
/// be written (under its final name), and leaves `dir` untouched.
void writeOwnedDirectory(const std::string& dir, const std::vector<OwnedFile>& files, const std::string& tool,
                         bool replace);

/// The same for content written by other code: `fill` writes the whole content into the
/// empty directory it is given (the temporary sibling; regular files and directories
/// only). `dir` is checked before `fill` runs, so a long job (training) is not started
/// for a directory that will be refused, and again before the swap. An ddace::Error from
/// `fill` naming the temporary directory is rethrown naming `dir`; any exception from
/// `fill` leaves `dir` untouched.
void writeOwnedDirectory(const std::string& dir, const std::function<void(const std::string& tmp_dir)>& fill,
                         const std::string& tool, bool replace);

}  // namespace ddace::task
