// sync.csv of a scene device (docs/scene-format.md): RadioSync rows, read and written.
#pragma once

#include <cstddef>
#include <string>

#include "locus/events.hpp"
#include "locus/scene/csv.hpp"

namespace locus::scene {

/// sync.csv: t, source (a non-empty id of at most NameTag::max_size() characters).
class SyncCsvReader {
 public:
  SyncCsvReader(const std::string& path, DeviceId device);
  bool next(RadioSync& out);

 private:
  CsvReader csv_;
  DeviceId device_;
  std::size_t t_, source_;
};

/// Writes sync.csv (t, source).
class SyncCsvWriter : public CsvWriter {
 public:
  explicit SyncCsvWriter(const std::string& path);
  void write(const RadioSync& s);
};

}  // namespace locus::scene
