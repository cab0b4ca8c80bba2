#pragma once
// Rewrites an MCAP file as McapWriter lays it out (chunks, message indexes, summary, CRCs): a recording cut
// short by kill -9 (no summary, a partial last record) or an older unchunked one. Reads the file record by
// record as a streamed reader does: every Schema and Channel, every Message (loose or in a chunk whose CRC
// checks), up to the first incomplete record; a chunk that fails its CRC or cannot be decompressed is skipped
// and counted. Not real-time code (the torque-mcap-recover tool and the tests).
#include <cstdint>
#include <string>

#include "mcap_writer.hpp"

namespace torqued::dash {

struct RecoverResult {
  std::string error;  ///< "" = written; else why not (the input is not MCAP, a write failed)
  std::uint64_t messages = 0, schemas = 0, channels = 0;
  std::uint64_t chunks_read = 0,
                chunks_bad = 0;  ///< complete input chunks; those skipped (CRC, decompression)
  bool input_closed = false;     ///< the input had its footer and closing magic
  std::uint64_t input_bytes = 0, bytes_dropped = 0;  ///< input size; bytes after its last complete record
};

RecoverResult recover_mcap(const std::string& in_path, const std::string& out_path,
                           const McapOptions& opt = {});

}  // namespace torqued::dash
