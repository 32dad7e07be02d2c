#include "data/text_input.hpp"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <fstream>
#include <limits>

namespace stiffid::data {

std::string read_text_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) throw InputError(path + ": cannot open (missing file or no permission)");
  std::string text(static_cast<size_t>(in.tellg()), '\0');
  in.seekg(0);
  if (!in.read(text.data(), static_cast<std::streamsize>(text.size()))) {
    throw InputError(path + ": read failed");
  }
  return text;
}

MappedText::MappedText(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw InputError(path + ": cannot open (missing file or no permission)");
  struct stat info {};
  if (::fstat(fd, &info) == 0 && S_ISREG(info.st_mode) && info.st_size > 0) {
    size_ = static_cast<std::size_t>(info.st_size);
    map_ = ::mmap(nullptr, size_, PROT_READ, MAP_PRIVATE | MAP_POPULATE, fd, 0);
    if (map_ == MAP_FAILED) map_ = nullptr;
  }
  ::close(fd);
  if (map_ != nullptr) {
    view_ = std::string_view(static_cast<const char*>(map_), size_);
  } else {
    copy_ = read_text_file(path);
    view_ = copy_;
  }
}

MappedText::~MappedText() {
  if (map_ != nullptr) ::munmap(map_, size_);
}

std::string line_column(const std::string& text, std::size_t offset) {
  int line = 1;
  int column = 1;
  for (std::size_t i = 0; i < offset && i < text.size(); ++i) {
    if (text[i] == '\n') {
      ++line;
      column = 1;
    } else {
      ++column;
    }
  }
  return std::to_string(line) + ":" + std::to_string(column);
}

const nlohmann::json& json_member(const nlohmann::json& j, const std::string& key,
                                  const std::string& path, const std::string& where,
                                  const std::string& expected) {
  if (!j.is_object() || !j.contains(key)) {
    throw InputError(path + ": missing key '" + where + key + "' (expected " + expected + ")");
  }
  return j.at(key);
}

std::vector<double> json_numbers(const nlohmann::json& j, const std::string& path,
                                 const std::string& key, std::size_t size, bool allow_null) {
  if (!j.is_array() || (size > 0 && j.size() != size)) {
    throw InputError(path + ": '" + key + "' must be an array of " +
                     (size > 0 ? std::to_string(size) + " " : std::string()) + "numbers");
  }
  std::vector<double> out;
  out.reserve(j.size());
  for (const auto& v : j) {
    if (allow_null && v.is_null()) {
      out.push_back(std::numeric_limits<double>::quiet_NaN());
    } else if (v.is_number()) {
      out.push_back(v.get<double>());
    } else {
      throw InputError(path + ": '" + key + "' holds a non-number");
    }
  }
  return out;
}

}  // namespace stiffid::data
