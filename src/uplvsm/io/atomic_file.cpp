// Crash-safe whole-file writes and checked whole-file reads (see atomic_file.h).
#include "uplvsm/io/atomic_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <stdexcept>

namespace uplvsm::io {
namespace fs = std::filesystem;

namespace {

std::runtime_error sys_error(const std::string& what, const std::string& path) {
  return std::runtime_error(what + " '" + path + "': " + std::strerror(errno));
}

void ensure_parent_dir(const std::string& path) {
  fs::path parent = fs::path(path).parent_path();
  if (parent.empty()) return;
  std::error_code ec;
  fs::create_directories(parent, ec);
  if (ec) throw std::runtime_error("cannot create directory '" + parent.string() + "': " + ec.message());
}

// Directory fsync makes the rename itself durable; failure here is not fatal (some filesystems refuse it).
void fsync_parent_dir(const std::string& path) {
  fs::path parent = fs::path(path).parent_path();
  if (parent.empty()) parent = ".";
  int fd = ::open(parent.c_str(), O_RDONLY | O_DIRECTORY);
  if (fd < 0) return;
  ::fsync(fd);
  ::close(fd);
}

void write_all(int fd, const uint8_t* p, size_t n, const std::string& path) {
  while (n > 0) {
    ssize_t w = ::write(fd, p, n);
    if (w < 0) {
      if (errno == EINTR) continue;
      throw sys_error("cannot write", path);
    }
    p += w;
    n -= static_cast<size_t>(w);
  }
}

}  // namespace

std::string temp_path_for(const std::string& path) {
  ensure_parent_dir(path);
  static std::atomic<uint64_t> counter{0};
  fs::path p(path);
  std::string name =
      "." + p.filename().string() + ".tmp." + std::to_string(::getpid()) + "." + std::to_string(counter.fetch_add(1));
  return (p.parent_path() / name).string();
}

void commit_temp_file(const std::string& tmp_path, const std::string& path) {
  int fd = ::open(tmp_path.c_str(), O_RDONLY);
  if (fd < 0) {
    auto err = sys_error("cannot reopen temporary file", tmp_path);
    ::unlink(tmp_path.c_str());
    throw err;
  }
  bool synced = ::fsync(fd) == 0;
  int saved = errno;
  ::close(fd);
  if (!synced) {
    errno = saved;
    auto err = sys_error("cannot fsync", tmp_path);
    ::unlink(tmp_path.c_str());
    throw err;
  }
  if (::rename(tmp_path.c_str(), path.c_str()) != 0) {
    auto err = sys_error("cannot rename temporary file onto", path);
    ::unlink(tmp_path.c_str());
    throw err;
  }
  fsync_parent_dir(path);
}

void write_file_atomic(const std::string& path, const void* data, size_t size) {
  write_file_atomic(path, std::vector<ByteSpan>{{data, size}});
}

void write_file_atomic(const std::string& path, const std::vector<ByteSpan>& parts) {
  std::string tmp = temp_path_for(path);
  int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) throw sys_error("cannot create temporary file for", path);
  try {
    for (const ByteSpan& part : parts) write_all(fd, static_cast<const uint8_t*>(part.data), part.size, path);
    if (::fsync(fd) != 0) throw sys_error("cannot fsync", path);
  } catch (...) {
    ::close(fd);
    ::unlink(tmp.c_str());
    throw;
  }
  if (::close(fd) != 0) {
    auto err = sys_error("cannot close", path);
    ::unlink(tmp.c_str());
    throw err;
  }
  if (::rename(tmp.c_str(), path.c_str()) != 0) {
    auto err = sys_error("cannot rename temporary file onto", path);
    ::unlink(tmp.c_str());
    throw err;
  }
  fsync_parent_dir(path);
}

std::vector<uint8_t> read_file(const std::string& path) {
  int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw sys_error("cannot open file", path);
  struct stat st {};
  if (::fstat(fd, &st) != 0) {
    ::close(fd);
    throw sys_error("cannot stat file", path);
  }
  if (S_ISDIR(st.st_mode)) {
    ::close(fd);
    throw std::runtime_error("cannot read '" + path + "': it is a directory");
  }
  std::vector<uint8_t> out(static_cast<size_t>(st.st_size));
  size_t done = 0;
  while (done < out.size()) {
    ssize_t r = ::read(fd, out.data() + done, out.size() - done);
    if (r < 0 && errno == EINTR) continue;
    if (r < 0) {
      ::close(fd);
      throw sys_error("cannot read file", path);
    }
    if (r == 0) break;  // file shrank while reading
    done += static_cast<size_t>(r);
  }
  ::close(fd);
  out.resize(done);
  return out;
}

}  // namespace uplvsm::io
