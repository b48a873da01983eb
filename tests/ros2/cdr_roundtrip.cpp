// The C++ half of the npm round-trip check of every message type (tests/ros2/npm/cdr_roundtrip.mjs,
// issue 35): samples serialized by another implementation go through the project's DDS layer and
// come back serialized by it.
//
//   cdr_roundtrip --list                  print the ROS name of every registered type, one a line
//   cdr_roundtrip --input IN --output OUT [--mutate]
//
// IN holds one sample a line: "pkg/msg/Type HEX", HEX the serialized sample (4-byte encapsulation
// header and payload). For each, on topics of its own in one participant, the tool
//   1. injects the bytes as they are with `dds_writecdr` (a serdata made from them by
//      `ddsi_serdata_from_ser_iov` with the topic's sertype, which Cyclone 0.10.2 only hands out
//      in a serdata: the tool takes it from a first, zeroed sample taken with `dds_takecdr`),
//   2. reads the sample with the typed `dds::Reader<T>`,
//   3. with --mutate, changes one value in it (the last primitive value or string, in
//      serialization order, found through the type's serializer ops), for the checker's
//      self-test,
//   4. writes the `Message<T>` read with the typed `dds::Writer<T>` on a second topic,
//   5. takes that sample's bytes with `dds::RawReader`,
// and writes to OUT "pkg/msg/Type HEX" with those bytes, or "pkg/msg/Type ERROR reason" when a
// step failed (bytes Cyclone refuses, no data before the deadline). Exit status 0 unless the
// input could not be read.
#include <dds/dds.h>
#include <dds/ddsc/dds_opcodes.h>
#include <dds/ddsi/ddsi_serdata.h>
#include <dds/ddsi/ddsi_sertype.h>
#include <dds/ddsrt/iovec.h>
#include <unistd.h>

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <exception>
#include <fstream>
#include <iostream>
#include <memory>
#include <span>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include "common/dds/messages.h"
#include "common/dds/participant.h"
#include "common/dds/qos.h"
#include "common/dds/raw.h"
#include "common/dds/reader.h"
#include "common/dds/writer.h"
#include "common/error.h"

namespace dds = autodrive::dds;
using namespace std::chrono_literals;

namespace {

constexpr auto kDeadline = 30s;

std::vector<std::byte> FromHex(std::string_view hex) {
  AUTODRIVE_THROW_UNLESS(hex.size() % 2 == 0, "odd number of hex digits");
  const auto digit = [](char c) -> unsigned {
    if (c >= '0' && c <= '9') return static_cast<unsigned>(c - '0');
    if (c >= 'a' && c <= 'f') return static_cast<unsigned>(c - 'a' + 10);
    if (c >= 'A' && c <= 'F') return static_cast<unsigned>(c - 'A' + 10);
    throw autodrive::InputError(std::string("not a hex digit: ") + c);
  };
  std::vector<std::byte> bytes(hex.size() / 2);
  for (std::size_t i = 0; i < bytes.size(); ++i) {
    bytes[i] = static_cast<std::byte>((digit(hex[2 * i]) << 4U) | digit(hex[2 * i + 1]));
  }
  return bytes;
}

std::string ToHex(std::span<const std::byte> bytes) {
  static constexpr char kDigits[] = "0123456789abcdef";
  std::string hex;
  hex.reserve(2 * bytes.size());
  for (const std::byte b : bytes) {
    const auto v = std::to_integer<unsigned>(b);
    hex.push_back(kDigits[v >> 4U]);
    hex.push_back(kDigits[v & 15U]);
  }
  return hex;
}

// Flips the lowest bit of the unsigned integer of type `U` at `p` (for a float, its last mantissa
// bit; a bool stays 0 or 1).
template <typename U>
void FlipLowBit(void* p) {
  U v = 0;
  std::memcpy(&v, p, sizeof v);
  v = static_cast<U>(v ^ 1U);
  std::memcpy(p, &v, sizeof v);
}

// --mutate: changes the primitive value of type code `type` at `p`; false for a type it does not
// change (enumerations, bitmasks: none in our types).
bool MutateValue(std::uint32_t type, void* p) {
  switch (type) {
    case DDS_OP_VAL_1BY:
    case DDS_OP_VAL_BLN:
      FlipLowBit<std::uint8_t>(p);
      return true;
    case DDS_OP_VAL_2BY:
      FlipLowBit<std::uint16_t>(p);
      return true;
    case DDS_OP_VAL_4BY:
      FlipLowBit<std::uint32_t>(p);
      return true;
    case DDS_OP_VAL_8BY:
      FlipLowBit<std::uint64_t>(p);
      return true;
    default:
      return false;
  }
}

// Changes the last character of a non-empty ASCII string (keeping it ASCII and its length).
bool MutateString(char* s) {
  if (s == nullptr || s[0] == '\0') return false;
  char& last = s[std::strlen(s) - 1];
  if (static_cast<unsigned char>(last) >= 0x80) return false;
  last = last == 'x' ? 'y' : 'x';
  return true;
}

// The size in memory of a primitive of type code `type`; 0 for any other.
std::size_t PrimitiveSize(std::uint32_t type) {
  switch (type) {
    case DDS_OP_VAL_1BY:
    case DDS_OP_VAL_BLN:
      return 1;
    case DDS_OP_VAL_2BY:
      return 2;
    case DDS_OP_VAL_4BY:
      return 4;
    case DDS_OP_VAL_8BY:
      return 8;
    default:
      return 0;
  }
}

// One value of a sample: a primitive of type code `type` at `p`, or (DDS_OP_VAL_STR) the string
// `p`.
struct Value {
  std::uint32_t type = 0;
  char* p = nullptr;
};

// Calls `visit` for every primitive value and every non-empty string of the sample at `data`
// laid out as `ops` (Cyclone's serializer program, dds_opcodes.h, of a final type: ADR
// instructions up to RTS), in the order they are serialized. False on a layout it does not
// follow (unions, enumerations, bitmasks, external or optional members: none in our types).
template <typename Visit>
bool ForEachValue(const std::uint32_t* ops, char* data, Visit& visit) {
  const auto string_at = [](const char* where) {
    char* s = nullptr;
    std::memcpy(&s, where, sizeof s);
    return s;
  };
  const auto visit_string = [&visit](char* s) {
    if (s != nullptr && s[0] != '\0') visit(Value{DDS_OP_VAL_STR, s});
  };
  for (const std::uint32_t* op = ops; DDS_OP(*op) != DDS_OP_RTS;) {
    if (DDS_OP(*op) != DDS_OP_ADR || (*op & (DDS_OP_FLAG_EXT | DDS_OP_FLAG_OPT)) != 0) return false;
    char* const addr = data + op[1];
    const std::uint32_t type = DDS_OP_TYPE(*op);
    const std::uint32_t subtype = DDS_OP_SUBTYPE(*op);
    switch (type) {
      case DDS_OP_VAL_1BY:
      case DDS_OP_VAL_2BY:
      case DDS_OP_VAL_4BY:
      case DDS_OP_VAL_8BY:
      case DDS_OP_VAL_BLN:
        visit(Value{type, addr});
        op += 2;
        break;
      case DDS_OP_VAL_STR:  // [offset]
        visit_string(string_at(addr));
        op += 2;
        break;
      case DDS_OP_VAL_BST:  // [offset] [max-size]
        visit_string(addr);
        op += 3;
        break;
      case DDS_OP_VAL_SEQ:
      case DDS_OP_VAL_BSQ: {  // [offset] [sbound (BSQ only)] ...
        dds_sequence_t seq;
        std::memcpy(&seq, addr, sizeof seq);
        const std::uint32_t* const rest = op + (type == DDS_OP_VAL_BSQ ? 3 : 2);
        char* const buffer = reinterpret_cast<char*>(seq._buffer);
        if (const std::size_t size = PrimitiveSize(subtype); size > 0) {
          for (std::uint32_t i = 0; i < seq._length; ++i) visit(Value{subtype, buffer + i * size});
          op = rest;
        } else if (subtype == DDS_OP_VAL_STR) {
          for (std::uint32_t i = 0; i < seq._length; ++i) {
            visit_string(string_at(buffer + i * sizeof(char*)));
          }
          op = rest;
        } else if (subtype == DDS_OP_VAL_STU) {  // [elem-size] [next-insn, elem-insn]
          for (std::uint32_t i = 0; i < seq._length; ++i) {
            if (!ForEachValue(op + DDS_OP_ADR_JSR(rest[1]), buffer + i * rest[0], visit)) {
              return false;
            }
          }
          op += DDS_OP_ADR_JMP(rest[1]);
        } else {
          return false;
        }
        break;
      }
      case DDS_OP_VAL_ARR: {  // [offset] [alen] ...
        const std::uint32_t length = op[2];
        if (const std::size_t size = PrimitiveSize(subtype); size > 0) {
          for (std::uint32_t i = 0; i < length; ++i) visit(Value{subtype, addr + i * size});
          op += 3;
        } else if (subtype == DDS_OP_VAL_STR) {
          for (std::uint32_t i = 0; i < length; ++i) {
            visit_string(string_at(addr + i * sizeof(char*)));
          }
          op += 3;
        } else if (subtype == DDS_OP_VAL_STU) {  // [next-insn, elem-insn] [elem-size]
          for (std::uint32_t i = 0; i < length; ++i) {
            if (!ForEachValue(op + DDS_OP_ADR_JSR(op[3]), addr + i * op[4], visit)) return false;
          }
          op += DDS_OP_ADR_JMP(op[3]);
        } else {
          return false;
        }
        break;
      }
      case DDS_OP_VAL_EXT:  // [offset] [next-insn, elem-insn]
        if (!ForEachValue(op + DDS_OP_ADR_JSR(op[2]), addr, visit)) return false;
        op += DDS_OP_ADR_JMP(op[2]);
        break;
      default:
        return false;
    }
  }
  return true;
}

// --mutate: changes the last value of the sample at `data` of type `descriptor` (the last in
// serialization order: usually deep in the last element of a sequence of messages, so that the
// checker must compare the whole sample to see it). True when it changed one.
bool MutateLast(const dds_topic_descriptor_t* descriptor, void* data) {
  Value last;
  auto remember = [&last](Value v) { last = v; };
  if (!ForEachValue(descriptor->m_ops, static_cast<char*>(data), remember) || last.p == nullptr) {
    return false;
  }
  return last.type == DDS_OP_VAL_STR ? MutateString(last.p) : MutateValue(last.type, last.p);
}

// One participant for the whole run, in a partition of its own so that concurrent tests on the
// loopback configuration never see its topics.
class RoundTrip {
 public:
  explicit RoundTrip(bool mutate) : mutate_(mutate), participant_(Options()) {}

  // The bytes our layer writes for `cdr` (a serialized `T`), or throws.
  template <dds::MessageType T>
  std::vector<std::byte> Run(std::string_view short_name, std::span<const std::byte> cdr) {
    const dds::MessageTypeInfo* info = dds::FindMessageType(dds::TypeName<T>());
    AUTODRIVE_CHECK(info != nullptr);
    const dds_topic_descriptor_t* descriptor = dds::MessageTraits<T>::descriptor();
    const std::string base =
        "rt/autodrive_cdr_roundtrip/" + std::to_string(++count_) + "/" + std::string(short_name);
    const dds::Qos qos = dds::Qos::Command();  // reliable, volatile, keep all

    // 1. The writer of the injected bytes and the sertype of its topic.
    dds::Writer<T> in_writer(participant_, base + "/in", qos);
    ddsi_sertype* sertype = SertypeOf<T>(in_writer, descriptor, base + "/in", qos);
    const std::unique_ptr<ddsi_sertype, void (*)(ddsi_sertype*)> owned_sertype(sertype,
                                                                               &ddsi_sertype_unref);

    // 2. The typed reader, created after the zeroed sample (volatile: it never sees that one).
    dds::Reader<T> reader(participant_, base + "/in", qos);
    AUTODRIVE_THROW_UNLESS(
        in_writer.WaitForReaders(1, kDeadline) && reader.WaitForWriters(1, kDeadline),
        "the typed reader of " << base << "/in never matched");
    ddsrt_iovec_t iov{};
    iov.iov_base = const_cast<std::byte*>(cdr.data());
    iov.iov_len = static_cast<decltype(iov.iov_len)>(cdr.size());
    ddsi_serdata* serdata = ddsi_serdata_from_ser_iov(sertype, SDK_DATA, 1, &iov, cdr.size());
    AUTODRIVE_THROW_UNLESS(serdata != nullptr, "Cyclone refuses the bytes ("
                                                   << cdr.size() << ") as a " << info->ros_type_name
                                                   << " (ddsi_serdata_from_ser_iov)");
    // dds_writecdr takes over the reference.
    dds::internal::ThrowIfError(dds_writecdr(in_writer.handle(), serdata), "dds_writecdr");

    dds::Message<T> message;
    const auto deadline = std::chrono::steady_clock::now() + kDeadline;
    while (!reader.TakeOne(message)) {
      AUTODRIVE_THROW_UNLESS(std::chrono::steady_clock::now() < deadline &&
                                 reader.WaitForData(deadline - std::chrono::steady_clock::now()),
                             "the typed reader of " << base << "/in got no sample");
    }
    if (mutate_) {
      AUTODRIVE_THROW_UNLESS(MutateLast(descriptor, &message.get()),
                             "--mutate found no value to change in the " << info->ros_type_name);
    }

    // 3. Written back by the typed writer, taken serialized.
    dds::Writer<T> out_writer(participant_, base + "/out", qos);
    dds::RawReader out_reader(participant_, base + "/out", descriptor, qos);
    AUTODRIVE_THROW_UNLESS(
        out_writer.WaitForReaders(1, kDeadline) && out_reader.WaitForWriters(1, kDeadline),
        "the raw reader of " << base << "/out never matched");
    out_writer.Write(message);
    dds::RawSample sample;
    while (!out_reader.Take(sample)) {
      AUTODRIVE_THROW_UNLESS(
          std::chrono::steady_clock::now() < deadline &&
              out_reader.WaitForData(deadline - std::chrono::steady_clock::now()),
          "the raw reader of " << base << "/out got no sample");
    }
    return sample.cdr;
  }

 private:
  // The sertype of `writer`'s topic (a reference the caller releases): from a zeroed sample it
  // writes, taken serialized by a reader that is gone on return.
  template <dds::MessageType T>
  ddsi_sertype* SertypeOf(dds::Writer<T>& writer, const dds_topic_descriptor_t* descriptor,
                          const std::string& topic, const dds::Qos& qos) {
    dds::internal::ReaderBase probe(participant_, descriptor, topic, qos);
    AUTODRIVE_THROW_UNLESS(
        writer.WaitForReaders(1, kDeadline) && probe.WaitForWriters(1, kDeadline),
        "the probe reader of " << topic << " never matched");
    writer.Write(dds::Message<T>());
    ddsi_sertype* sertype = nullptr;
    const auto deadline = std::chrono::steady_clock::now() + kDeadline;
    const auto take = [&sertype](dds_entity_t handle, dds_instance_handle_t* publication) -> int {
      ddsi_serdata* data = nullptr;
      dds_sample_info_t sample_info;
      const dds_return_t n = dds::internal::ThrowIfError(
          dds_takecdr(handle, &data, 1, &sample_info, DDS_ANY_STATE), "dds_takecdr");
      if (n == 0) return 0;
      sertype = ddsi_sertype_ref(data->type);
      *publication = sample_info.publication_handle;
      ddsi_serdata_unref(data);
      return 1;
    };
    while (!probe.TakeWith(take)) {
      AUTODRIVE_THROW_UNLESS(std::chrono::steady_clock::now() < deadline &&
                                 probe.WaitForData(deadline - std::chrono::steady_clock::now()),
                             "the probe reader of " << topic << " got no sample");
    }
    return sertype;
  }

  static dds::ParticipantOptions Options() {
    dds::ParticipantOptions options;
    options.partition = "autodrive_cdr_roundtrip_" + std::to_string(::getpid());
    return options;
  }

  bool mutate_;
  dds::Participant participant_;
  int count_ = 0;
};

int Main(int argc, char** argv) {
  bool list = false;
  bool mutate = false;
  std::string input;
  std::string output;
  for (int i = 1; i < argc; ++i) {
    const std::string_view arg = argv[i];
    if (arg == "--list") {
      list = true;
    } else if (arg == "--mutate") {
      mutate = true;
    } else if ((arg == "--input" || arg == "--output") && i + 1 < argc) {
      (arg == "--input" ? input : output) = argv[++i];
    } else {
      std::cerr << "usage: cdr_roundtrip --list | --input IN --output OUT [--mutate]\n";
      return 2;
    }
  }
  if (list) {
    for (const dds::MessageTypeInfo& t : dds::MessageTypes()) std::cout << t.ros_type_name << '\n';
    return 0;
  }
  if (input.empty() || output.empty()) {
    std::cerr << "cdr_roundtrip: --input and --output are required\n";
    return 2;
  }
  std::ifstream in(input);
  AUTODRIVE_THROW_UNLESS(in, "cannot read " << input);
  std::ofstream out(output);
  AUTODRIVE_THROW_UNLESS(out, "cannot write " << output);
  RoundTrip round_trip(mutate);
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty()) continue;
    std::istringstream fields(line);
    std::string type_name;
    std::string hex;
    fields >> type_name >> hex;
    try {
      const dds::MessageTypeInfo* info = dds::FindMessageType(type_name);
      AUTODRIVE_THROW_UNLESS(info != nullptr, "no registered type " << type_name);
      const std::vector<std::byte> cdr = FromHex(hex);
      std::vector<std::byte> result;
      bool found = false;
#define AUTODRIVE_CDR_DISPATCH_(c_type, name)         \
  if (!found && info->descriptor == &c_type##_desc) { \
    result = round_trip.Run<c_type>(#name, cdr);      \
    found = true;                                     \
  }
      AUTODRIVE_DDS_MESSAGE_TYPES(AUTODRIVE_CDR_DISPATCH_)
#undef AUTODRIVE_CDR_DISPATCH_
      AUTODRIVE_THROW_UNLESS(found, "no typed reader for " << type_name);
      out << type_name << ' ' << ToHex(result) << '\n';
    } catch (const std::exception& e) {
      out << type_name << " ERROR " << e.what() << '\n';
    }
  }
  out.flush();
  AUTODRIVE_THROW_UNLESS(out, "cannot write " << output);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return Main(argc, argv);
  } catch (const std::exception& e) {
    std::cerr << "cdr_roundtrip: " << e.what() << '\n';
    return 1;
  }
}
