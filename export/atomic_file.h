#pragma once
// Files written completely or not at all: data goes to a temporary name in
// the same directory, is flushed, and is renamed over the target.
#include <functional>
#include <initializer_list>
#include <ostream>
#include <string>

namespace triad {

// Calls write(stream) on a temporary file beside `path`, then renames it to
// `path`. On any failure the temporary is removed, `path` is left as it was,
// and std::runtime_error names the file.
void writeFileAtomically(const std::string& path, const std::function<void(std::ostream&)>& write);

// The same for writers that want a file name rather than a stream (OpenVDB,
// libpng): write_to(tmp) writes the temporary, which is then renamed.
void writeFileViaTemporary(const std::string& path,
                           const std::function<void(const std::string& tmp)>& write_to);

// Renames a temporary written elsewhere (by several processes at once) to
// `path`; on failure removes it and throws std::runtime_error naming `path`.
void moveIntoPlace(const std::string& tmp, const std::string& path);
// Removes such temporaries (empty names are skipped), quietly: for the
// files of a frame that failed.
void removeTemporaries(std::initializer_list<std::string> tmps);

// Creates a directory and its parents; throws std::runtime_error naming it.
void makeDirectories(const std::string& path);

}  // namespace triad
