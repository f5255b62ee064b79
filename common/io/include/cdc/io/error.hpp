// The error every reader in common/io throws for input that is not what it claims to be.
#pragma once

#include <stdexcept>

namespace cdc::io {

// A file, recording or packet that cannot be read: what() names the file and the place (byte offset,
// line, record, row or message index) where reading stopped.
class FormatError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace cdc::io
