// One field of /proc/self/status (VmRSS, VmHWM, ...) in kB, for the benchmarks' memory figures; -1 if absent.
#pragma once

#include <cstdlib>
#include <cstring>
#include <fstream>
#include <string>

namespace lodforge::bench {

inline long status_kb(const char* key) {
  std::ifstream f("/proc/self/status");
  std::string line;
  const std::size_t n = std::strlen(key);
  while (std::getline(f, line))
    if (line.compare(0, n, key) == 0) return std::strtol(line.c_str() + n, nullptr, 10);
  return -1;
}

}  // namespace lodforge::bench
