#include "cdc/dds/traffic.hpp"

#include <dds/ddsi/ddsi_cdrstream.h>

#include <charconv>
#include <cstdio>
#include <cstring>
#include <memory>
#include <mutex>

namespace cdc::dds {
namespace {

struct Registry {
  std::mutex mutex;
  std::map<std::pair<uint32_t, std::string>, std::unique_ptr<TopicCounters>> topics;
};

Registry& registry() {
  static Registry r;
  return r;
}

// XCDR1 body size of a sample, walked from the type's serialiser instructions (dds_opcodes.h)
// without writing it: what Cyclone's dds_stream_write would produce, at a fraction of the cost for
// long sequences of structs (a LiDAR sweep). Only the instructions cdc-slam's IDL compiles to are
// walked; anything else (unions, bitmasks, optional or external members, bounded strings, ...)
// returns false and the caller serialises the sample instead.

size_t align_to(size_t pos, size_t a) { return (pos + a - 1) / a * a; }
size_t pad4(size_t n) { return align_to(n, 4); }  // DDSI pads every payload to 4 bytes

// Wire size of a primitive type code, 0 when it is not one.
size_t primitive_size(uint32_t type) {
  switch (type) {
    case DDS_OP_VAL_1BY:
    case DDS_OP_VAL_BLN:
      return 1;
    case DDS_OP_VAL_2BY:
      return 2;
    case DDS_OP_VAL_4BY:
    case DDS_OP_VAL_ENU:
      return 4;  // XCDR1 sends every enum as 4 bytes
    case DDS_OP_VAL_8BY:
      return 8;
    default:
      return 0;
  }
}

// Adds n primitives of `size` bytes at pos (XCDR1 aligns each to its size, 8 included).
void add_primitives(size_t& pos, size_t size, size_t n) {
  if (n == 0) return;
  pos = align_to(pos, size) + size * n;
}

bool measure_struct(const uint32_t* ops, const char* data, size_t& pos);

// A struct element's size depends on where it starts only through pos mod 8 when it holds nothing
// but fixed-size members; true for those, with the advance from each start residue in `delta`.
bool is_fixed_size(const uint32_t* ops) {
  for (const uint32_t* op = ops; DDS_OP(*op) != DDS_OP_RTS;) {
    if (DDS_OP(*op) != DDS_OP_ADR || (*op & DDS_OP_FLAG_EXT) != 0) return false;
    const uint32_t type = DDS_OP_TYPE(*op);
    if (primitive_size(type) > 0) {
      op += type == DDS_OP_VAL_ENU ? 3 : 2;
    } else if (type == DDS_OP_VAL_ARR && primitive_size(DDS_OP_SUBTYPE(*op)) > 0 &&
               DDS_OP_SUBTYPE(*op) != DDS_OP_VAL_ENU) {
      op += 3;
    } else if (type == DDS_OP_VAL_EXT) {
      if (!is_fixed_size(op + DDS_OP_ADR_JSR(op[2]))) return false;
      op += DDS_OP_ADR_JMP(op[2]);
    } else {
      return false;  // sequences and strings: walked element by element
    }
  }
  return true;
}

bool fixed_element_deltas(const uint32_t* elem_ops, size_t (&delta)[8]) {
  if (!is_fixed_size(elem_ops)) return false;
  for (size_t r = 0; r < 8; ++r) {
    size_t pos = r;
    if (!measure_struct(elem_ops, nullptr, pos)) return false;
    delta[r] = pos - r;
  }
  return true;
}

// Adds n struct elements laid out `stride` bytes apart in memory from `first`.
bool add_struct_elements(size_t& pos, const uint32_t* elem_ops, const char* first, size_t stride, size_t n) {
  if (n == 0) return true;
  size_t delta[8];
  if (fixed_element_deltas(elem_ops, delta)) {
    for (size_t i = 0; i < n; ++i) pos += delta[pos & 7u];
    return true;
  }
  for (size_t i = 0; i < n; ++i) {
    if (!measure_struct(elem_ops, first + i * stride, pos)) return false;
  }
  return true;
}

// Walks one struct's members up to its RTS. `data` may be null for fixed-size structs.
bool measure_struct(const uint32_t* ops, const char* data, size_t& pos) {
  constexpr uint32_t kPlainFlags = DDS_OP_FLAG_KEY | DDS_OP_FLAG_FP | DDS_OP_FLAG_SGN | DDS_OP_FLAG_MU;
  for (const uint32_t* op = ops; DDS_OP(*op) != DDS_OP_RTS;) {
    if (DDS_OP(*op) != DDS_OP_ADR || (*op & DDS_OP_FLAG_EXT) != 0) return false;
    const uint32_t type = DDS_OP_TYPE(*op);
    const uint32_t flags = DDS_OP_FLAGS(*op) & ~(type == DDS_OP_VAL_ENU ? DDS_OP_FLAG_SZ_MASK : 0u);
    if ((flags & ~kPlainFlags) != 0) return false;
    const char* addr = data == nullptr ? nullptr : data + op[1];
    if (const size_t size = primitive_size(type); size > 0) {
      add_primitives(pos, size, 1);
      op += type == DDS_OP_VAL_ENU ? 3 : 2;  // [ADR, ENU] [offset] [max]
      continue;
    }
    const uint32_t sub = DDS_OP_SUBTYPE(*op);
    switch (type) {
      case DDS_OP_VAL_STR: {  // [ADR, STR] [offset]: length (with the NUL) then the bytes
        if (addr == nullptr) return false;
        const char* str = *reinterpret_cast<const char* const*>(addr);
        pos = align_to(pos, 4) + 4 + (str == nullptr ? 1 : std::strlen(str) + 1);
        op += 2;
        break;
      }
      case DDS_OP_VAL_ARR: {  // [ADR, ARR, nBY] [offset] [alen]
        const size_t size = primitive_size(sub);
        if (size == 0 || sub == DDS_OP_VAL_ENU) return false;
        add_primitives(pos, size, op[2]);
        op += 3;
        break;
      }
      case DDS_OP_VAL_SEQ: {
        if (addr == nullptr) return false;
        const auto* seq = reinterpret_cast<const dds_sequence_t*>(addr);
        pos = align_to(pos, 4) + 4;  // the length
        if (const size_t size = primitive_size(sub); size > 0 && sub != DDS_OP_VAL_ENU) {
          add_primitives(pos, size, seq->_length);  // [ADR, SEQ, nBY] [offset]
          op += 2;
        } else if (sub == DDS_OP_VAL_STU) {  // [ADR, SEQ, STU] [offset] [elem-size] [next-insn, elem-insn]
          const uint32_t* elem_ops = op + DDS_OP_ADR_JSR(op[3]);
          if (!add_struct_elements(pos, elem_ops, reinterpret_cast<const char*>(seq->_buffer), op[2], seq->_length)) {
            return false;
          }
          op += DDS_OP_ADR_JMP(op[3]);
        } else {
          return false;
        }
        break;
      }
      case DDS_OP_VAL_EXT: {  // [ADR, EXT] [offset] [next-insn, elem-insn]: a nested struct, inline
        if (!measure_struct(op + DDS_OP_ADR_JSR(op[2]), addr, pos)) return false;
        op += DDS_OP_ADR_JMP(op[2]);
        break;
      }
      default:
        return false;
    }
  }
  return true;
}

}  // namespace

TopicCounters& topic_counters(uint32_t domain, const std::string& topic) {
  Registry& r = registry();
  const std::lock_guard<std::mutex> lock(r.mutex);
  auto& slot = r.topics[{domain, topic}];
  if (!slot) slot = std::make_unique<TopicCounters>();
  return *slot;
}

bool count_undecodable_message(uint32_t domain, std::string_view message) {
  // "data(application, vendor 1.16): <guid> #<seq>: deserialization <topic>/<type> failed (<reason>)"; topic
  // names hold slashes, type names ("cdc::msg::Loop") do not.
  constexpr std::string_view kWhat = ": deserialization ", kFailed = " failed";
  if (message.rfind("data(application", 0) != 0) return false;
  const size_t at = message.find(kWhat);
  if (at == std::string_view::npos) return false;
  const size_t start = at + kWhat.size();
  const size_t end = message.find(kFailed, start);
  if (end == std::string_view::npos) return false;
  const size_t slash = message.substr(start, end - start).rfind('/');
  if (slash == std::string_view::npos || slash == 0) return false;
  topic_counters(domain, std::string(message.substr(start, slash))).undecodable.fetch_add(1);
  return true;
}

namespace {

// The domain a message comes from, as its header ("<time> [<domain>] <thread>: ") names it: Cyclone's log data
// gives 0 for every domain.
uint32_t domain_of(const dds_log_data_t* data) {
  const std::string_view header(data->message - data->hdrsize, data->hdrsize);
  const size_t open = header.find('['), close = header.find(']');
  uint32_t domain = 0;
  if (open == std::string_view::npos || close == std::string_view::npos || close <= open + 1) return data->domid;
  const auto [end, ec] = std::from_chars(header.data() + open + 1, header.data() + close, domain);
  return ec == std::errc() && end == header.data() + close ? domain : data->domid;
}

void undecodable_log_sink(void*, const dds_log_data_t* data) {
  count_undecodable_message(domain_of(data), std::string_view(data->message, data->size));
  // What Cyclone's default sink does: the header, then the message.
  std::fwrite(data->message - data->hdrsize, 1, data->hdrsize + data->size, stderr);
  if (data->size == 0 || data->message[data->size - 1] != '\n') std::fputc('\n', stderr);
  std::fflush(stderr);
}

}  // namespace

void watch_undecodable_samples() {
  static std::once_flag once;
  std::call_once(once, [] { dds_set_log_sink(undecodable_log_sink, nullptr); });
}

std::map<std::pair<uint32_t, std::string>, TopicTotals> topic_traffic() {
  Registry& r = registry();
  const std::lock_guard<std::mutex> lock(r.mutex);
  std::map<std::pair<uint32_t, std::string>, TopicTotals> out;
  for (const auto& [key, c] : r.topics) {
    out[key] = {c->samples_written.load(), c->bytes_written.load(), c->samples_taken.load(),   c->bytes_taken.load(),
                c->undecodable.load(),     c->samples_lost.load(),  c->samples_rejected.load()};
  }
  return out;
}

size_t serialized_size_by_writing(const dds_topic_descriptor_t* descriptor, const void* sample) {
  constexpr size_t kEncapsulation = 4;  // the encapsulation header
  constexpr uint32_t kXcdr1 = 1;        // CDR_ENC_VERSION_1 (dds/ddsi/q_protocol.h)
  dds_ostream_t os;
  dds_ostream_init(&os, 0, kXcdr1);
  dds_stream_write(&os, static_cast<const char*>(sample), descriptor->m_ops);
  const size_t n = os.m_index;
  dds_ostream_fini(&os);
  return kEncapsulation + pad4(n);
}

bool walked_serialized_size(const dds_topic_descriptor_t* descriptor, const void* sample, size_t& size) {
  constexpr size_t kEncapsulation = 4;
  size_t body = 0;
  if (!measure_struct(descriptor->m_ops, static_cast<const char*>(sample), body)) return false;
  size = kEncapsulation + pad4(body);
  return true;
}

size_t serialized_size(const dds_topic_descriptor_t* descriptor, const void* sample) {
  size_t size = 0;
  return walked_serialized_size(descriptor, sample, size) ? size : serialized_size_by_writing(descriptor, sample);
}

}  // namespace cdc::dds
