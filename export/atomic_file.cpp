#include "export/atomic_file.h"

#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <system_error>

namespace triad {

namespace fs = std::filesystem;

void writeFileViaTemporary(const std::string& path,
                           const std::function<void(const std::string& tmp)>& write_to) {
  // A unique temporary name per process, so concurrent writers never collide.
  const std::string tmp = path + ".tmp" + std::to_string(::getpid());
  try {
    write_to(tmp);
    std::error_code ec;
    fs::rename(tmp, path, ec);
    if (ec) throw std::runtime_error("cannot rename into place: " + ec.message());
  } catch (const std::exception& e) {
    std::error_code ignored;
    fs::remove(tmp, ignored);
    throw std::runtime_error(path + ": " + e.what());
  }
}

void writeFileAtomically(const std::string& path,
                         const std::function<void(std::ostream&)>& write) {
  writeFileViaTemporary(path, [&](const std::string& tmp) {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw std::runtime_error("cannot open for writing");
    write(out);
    out.flush();
    if (!out) throw std::runtime_error("write failed (disk full?)");
  });
}

void moveIntoPlace(const std::string& tmp, const std::string& path) {
  std::error_code ec;
  fs::rename(tmp, path, ec);
  if (!ec) return;
  std::error_code ignored;
  fs::remove(tmp, ignored);
  throw std::runtime_error(path + ": cannot rename into place: " + ec.message());
}

void removeTemporaries(std::initializer_list<std::string> tmps) {
  for (const std::string& tmp : tmps) {
    if (tmp.empty()) continue;
    std::error_code ignored;
    fs::remove(tmp, ignored);
  }
}

void makeDirectories(const std::string& path) {
  std::error_code ec;
  fs::create_directories(path, ec);
  if (ec || !fs::is_directory(path))
    throw std::runtime_error(path + ": cannot create directory" +
                             (ec ? ": " + ec.message() : std::string()));
}

}  // namespace triad
