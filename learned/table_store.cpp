#include "table_store.hpp"

#include <elf.h>
#include <fcntl.h>
#include <link.h>
#include <unistd.h>

#include <cerrno>
#include <cinttypes>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <utility>

namespace torqued {

namespace {
constexpr char kMagic[8] = {'T', 'Q', 'T', 'A', 'B', 'L', 'E', '1'};
constexpr std::size_t kHeaderWords = 4;  // magic, key, binary id, count

/// 64-bit FNV-1a over 8-byte words (the file is a sequence of them).
std::uint64_t checksum(const void* words, std::size_t n, std::uint64_t h = 0xcbf29ce484222325ULL) noexcept {
  const auto* p = static_cast<const unsigned char*>(words);
  for (std::size_t i = 0; i < n; ++i) {
    std::uint64_t w;
    std::memcpy(&w, p + 8 * i, 8);
    h = (h ^ w) * 0x100000001b3ULL;
  }
  return h;
}

std::string hex16(std::uint64_t v) {
  char b[17];
  std::snprintf(b, sizeof b, "%016" PRIx64, v);
  return b;
}

int note_of_main(dl_phdr_info* info, std::size_t, void* out) {
  // The first object dl_iterate_phdr reports is the executable itself.
  auto* id = static_cast<std::uint64_t*>(out);
  for (int i = 0; i < info->dlpi_phnum; ++i) {
    const ElfW(Phdr)& ph = info->dlpi_phdr[i];
    if (ph.p_type != PT_NOTE) continue;
    // The loader gives the object's load address as an integer (dl_iterate_phdr's interface).
    const auto* p = reinterpret_cast<const unsigned char*>(  // NOLINT(performance-no-int-to-ptr)
        info->dlpi_addr + ph.p_vaddr);
    const unsigned char* end = p + ph.p_memsz;
    while (p + sizeof(ElfW(Nhdr)) <= end) {
      ElfW(Nhdr) nh;
      std::memcpy(&nh, p, sizeof nh);
      const unsigned char* name = p + sizeof nh;
      const unsigned char* desc = name + ((nh.n_namesz + 3) & ~3U);
      if (nh.n_type == NT_GNU_BUILD_ID && nh.n_namesz == 4 && std::memcmp(name, "GNU", 4) == 0 &&
          desc + nh.n_descsz <= end) {
        TableKey k;
        k.bytes(desc, nh.n_descsz);
        *id = k.value();
        return 1;
      }
      p = desc + ((nh.n_descsz + 3) & ~3U);
    }
  }
  return 1;  // only the executable
}

bool write_all(int fd, const void* data, std::size_t n) {
  const auto* p = static_cast<const char*>(data);
  while (n > 0) {
    const ssize_t w = ::write(fd, p, n);
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) return false;
    p += w;
    n -= static_cast<std::size_t>(w);
  }
  return true;
}

void fsync_dir(const std::string& dir) {
  const int dfd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dfd < 0) return;
  ::fsync(dfd);
  ::close(dfd);
}
}  // namespace

std::uint64_t executable_build_id() noexcept {
  std::uint64_t id = 0;
  dl_iterate_phdr(note_of_main, &id);
  return id;
}

std::string table_dir_for(const std::string& configured, const std::string& state_dir) {
  if (configured == "off") return {};
  if (!configured.empty()) return configured;
  if (!state_dir.empty()) return state_dir + "/tables";
  if (const char* x = std::getenv("XDG_CACHE_HOME"); x && *x == '/') return std::string(x) + "/torqued";
  if (const char* h = std::getenv("HOME"); h && *h == '/') return std::string(h) + "/.cache/torqued";
  return {};
}

TableStore::TableStore(std::string dir, std::uint64_t binary_id, Reporter reporter)
    : dir_(std::move(dir)),
      binary_id_(binary_id != 0 ? binary_id : executable_build_id()),
      reporter_(std::move(reporter)) {}

void TableStore::note(std::string message, bool warning) {
  if (reporter_)
    reporter_(message, warning);
  else
    messages_.push_back(std::move(message));
}

std::string TableStore::path_of(std::string_view kind, std::uint64_t key) const {
  return dir_ + "/" + std::string(kind) + "-" + hex16(key) + ".bin";
}

std::optional<std::vector<double>> TableStore::load(std::string_view kind, std::uint64_t key) {
  if (!usable()) return std::nullopt;
  const std::string path = path_of(kind, key);
  std::lock_guard lk(mu_);
  // A file of another build or key is expected after an upgrade (info); a damaged one is not (warning).
  auto reject = [&](const char* why, bool damaged = true) -> std::optional<std::vector<double>> {
    note("table cache: " + path + " not used (" + why + "): recomputed", damaged);
    return std::nullopt;
  };
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) return std::nullopt;  // not cached yet: the store after the computation says so
  std::uint64_t head[kHeaderWords + 1];
  std::vector<double> t;
  const bool got_head = std::fread(head, 8, kHeaderWords, f) == kHeaderWords;
  // Count bounded by the file's size before allocating (a corrupt count must not allocate terabytes).
  std::error_code ec;
  const auto size = std::filesystem::file_size(path, ec);
  const bool sized = got_head && !ec && head[3] < size / 8 && size == 8 * (kHeaderWords + 1 + head[3]);
  if (sized) {
    t.resize(head[3]);
    if (std::fread(t.data(), 8, t.size(), f) != t.size() || std::fread(&head[kHeaderWords], 8, 1, f) != 1)
      t.clear();
  }
  std::fclose(f);
  if (!got_head || std::memcmp(head, kMagic, 8) != 0) return reject("not a table file");
  if (!sized || t.size() != head[3]) return reject("truncated or size mismatch");
  std::uint64_t sum = checksum(head, kHeaderWords, 0xcbf29ce484222325ULL);
  sum = checksum(t.data(), t.size(), sum);
  if (sum != head[kHeaderWords]) return reject("checksum mismatch: corrupt");
  if (head[1] != key) return reject("key mismatch", false);
  if (head[2] != binary_id_) return reject("written by another build", false);
  ++hits_;
  note("table cache: " + std::string(kind) + " loaded from " + path, false);
  return t;
}

void TableStore::store(std::string_view kind, std::uint64_t key, std::span<const double> table) {
  if (!usable()) return;
  const std::string path = path_of(kind, key);
  std::lock_guard lk(mu_);
  ++misses_;
  // Header, the table's own bytes and the checksum, written without copying the table (a copy and a
  // zero-filled buffer of its size were two thirds of a first start-up's store of the Kalman gains).
  std::uint64_t head[kHeaderWords];
  std::memcpy(head, kMagic, 8);
  head[1] = key;
  head[2] = binary_id_;
  head[3] = table.size();
  const std::uint64_t sum = checksum(table.data(), table.size(), checksum(head, kHeaderWords));
  std::error_code ec;
  std::filesystem::create_directories(dir_, ec);
  const std::string tmp = path + ".tmp." + std::to_string(::getpid());
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  bool ok = fd >= 0 && write_all(fd, head, sizeof head) && write_all(fd, table.data(), table.size_bytes()) &&
            write_all(fd, &sum, sizeof sum) && ::fsync(fd) == 0;
  if (fd >= 0) ok = (::close(fd) == 0) && ok;
  if (ok) ok = ::rename(tmp.c_str(), path.c_str()) == 0;
  if (!ok) {
    note("table cache: " + std::string(kind) + " computed, not stored in " + dir_ + " (" +
             std::strerror(errno) + ")",
         false);  // a read-only or absent cache directory only costs the next start the computation
    ::unlink(tmp.c_str());
    return;
  }
  fsync_dir(dir_);
  note("table cache: " + std::string(kind) + " computed and stored in " + path, false);
}

std::vector<std::string> TableStore::take_messages() {
  std::lock_guard lk(mu_);
  return std::exchange(messages_, {});
}

}  // namespace torqued
