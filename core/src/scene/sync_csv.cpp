// sync.csv (sync_csv.hpp).
#include "locus/scene/sync_csv.hpp"

#include <string>

#include "stream_detail.hpp"

namespace locus::scene {

using detail::shown;
using detail::trim;

SyncCsvReader::SyncCsvReader(const std::string& path, DeviceId device) : csv_(path), device_(device) {
  t_ = csv_.require_column("t");
  source_ = csv_.require_column("source");
}

bool SyncCsvReader::next(RadioSync& out) {
  if (!csv_.next_row()) return false;
  RadioSync s;
  s.device = device_;
  s.t_s = csv_.number(t_);
  const std::string_view src = trim(csv_.field(source_));
  if (src.empty()) csv_.fail(source_, "expected a sender id, got an empty field");
  if (src.size() > NameTag::max_size())
    csv_.fail(source_, "sender id " + shown(src) + " is longer than " + std::to_string(NameTag::max_size()) +
                           " characters");
  s.source = src;
  out = s;
  return true;
}

SyncCsvWriter::SyncCsvWriter(const std::string& path) : CsvWriter(path, {"t", "source"}) {}

void SyncCsvWriter::write(const RadioSync& s) { row({format_double(s.t_s), s.source.str()}); }

}  // namespace locus::scene
