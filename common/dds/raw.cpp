#include "common/dds/raw.h"

#include <dds/ddsi/ddsi_cdrstream.h>
#include <dds/ddsi/ddsi_serdata.h>
#include <dds/ddsi/q_protocol.h>

#include <algorithm>
#include <cstring>
#include <memory>

#include "common/dds/messages.h"
#include "common/error.h"

namespace autodrive::dds {

std::string RosTypeName(std::string_view dds_type_name) {
  // "pkg::msg::dds_::Type_" -> "pkg/msg/Type".
  constexpr std::string_view kMiddle = "::msg::dds_::";
  const auto middle = dds_type_name.find(kMiddle);
  if (middle == std::string_view::npos || middle == 0 || dds_type_name.size() < 2 ||
      dds_type_name.back() != '_') {
    return {};
  }
  const std::string_view type = dds_type_name.substr(
      middle + kMiddle.size(), dds_type_name.size() - middle - kMiddle.size() - 1);
  if (type.empty() || type.find(':') != std::string_view::npos) return {};
  return std::string(dds_type_name.substr(0, middle)) + "/msg/" + std::string(type);
}

const std::vector<MessageTypeInfo>& MessageTypes() {
  static const std::vector<MessageTypeInfo> kTypes = [] {
    std::vector<MessageTypeInfo> types;
    for (const dds_topic_descriptor_t* d : AllMessageDescriptors()) {
      types.push_back({d->m_typename, RosTypeName(d->m_typename), d});
    }
    return types;
  }();
  return kTypes;
}

const MessageTypeInfo* FindMessageType(std::string_view name) {
  for (const MessageTypeInfo& t : MessageTypes()) {
    if (t.dds_type_name == name || t.ros_type_name == name) return &t;
  }
  return nullptr;
}

RawReader::RawReader(const Participant& participant, const std::string& topic_name,
                     const dds_topic_descriptor_t* descriptor, const Qos& qos)
    : base_(participant, descriptor, topic_name, qos) {}

bool RawReader::Take(RawSample& sample) {
  return base_.TakeWith([&sample](dds_entity_t reader, dds_instance_handle_t* publication) -> int {
    ddsi_serdata* data = nullptr;
    dds_sample_info_t info;
    const dds_return_t n =
        internal::ThrowIfError(dds_takecdr(reader, &data, 1, &info, DDS_ANY_STATE), "dds_takecdr");
    if (n == 0) return 0;
    // The serdata is ours now: unreference it whatever happens below.
    const std::unique_ptr<ddsi_serdata, void (*)(ddsi_serdata*)> owned(data, &ddsi_serdata_unref);
    if (!info.valid_data) return -1;  // lifecycle only (disposed, unregistered): skip it
    const std::uint32_t size = ddsi_serdata_size(data);
    sample.cdr.resize(size);
    ddsi_serdata_to_ser(data, 0, size, sample.cdr.data());
    *publication = info.publication_handle;
    sample.source_timestamp_ns = info.source_timestamp;
    sample.publication_handle = info.publication_handle;
    return 1;
  });
}

RawWriter::RawWriter(const Participant& participant, const std::string& topic_name,
                     const dds_topic_descriptor_t* descriptor, const Qos& qos)
    : topic_name_(topic_name),
      descriptor_(descriptor),
      topic_(internal::CreateTopic(participant, descriptor, topic_name)),
      writer_(dds_create_writer(participant.publisher(), topic_.handle(),
                                internal::MakeEndpointQos(qos, descriptor).get(), nullptr),
              "dds_create_writer(" + topic_name + ")"),
      ros_graph_entry_(participant.ListInRosGraph(writer_.handle(), /*reader=*/false)) {}

namespace {
/// Frees a deserialized sample's strings and sequences, and the sample.
struct SampleDeleter {
  const dds_topic_descriptor_t* descriptor;
  void operator()(void* sample) const {
    dds_stream_free_sample(sample, descriptor->m_ops);
    std::free(sample);  // NOLINT(cppcoreguidelines-no-malloc): pairs with calloc below
  }
};
}  // namespace

void RawWriter::Write(std::span<const std::byte> cdr) {
  AUTODRIVE_THROW_UNLESS(cdr.size() >= 4, "a serialized "
                                              << descriptor_->m_typename << " on " << topic_name_
                                              << " has " << cdr.size()
                                              << " bytes: not even an encapsulation header");
  const unsigned identifier =
      (std::to_integer<unsigned>(cdr[0]) << 8U) | std::to_integer<unsigned>(cdr[1]);
  // CDR_BE/CDR_LE are XCDR1; CDR2_BE/LE and D_CDR2_BE/LE are XCDR2 (the same bytes for our
  // final types). Parameter-list encodings are for mutable types, which we have none of.
  std::uint32_t xcdr_version = 0;
  switch (identifier) {
    case 0x0000:
    case 0x0001:
      xcdr_version = CDR_ENC_VERSION_1;
      break;
    case 0x0006:
    case 0x0007:
    case 0x0008:
    case 0x0009:
      xcdr_version = CDR_ENC_VERSION_2;
      break;
    default:
      throw InputError("a serialized " + std::string(descriptor_->m_typename) + " on " +
                       topic_name_ + " has encapsulation " + std::to_string(identifier) +
                       ": only plain CDR and XCDR2 (0x0000/0x0001, 0x0006-0x0009) can be written");
  }
  const bool little_endian_input = (identifier & 1U) != 0;
  const bool bswap = little_endian_input != (DDSRT_ENDIAN == DDSRT_LITTLE_ENDIAN);
  const std::span<const std::byte> payload = cdr.subspan(4);
  AUTODRIVE_CHECK(payload.size() <= UINT32_MAX);
  scratch_.assign(payload.begin(), payload.end());
  std::uint32_t end = 0;
  // Checks every length, bound and enumerator against the type and byte-swaps in place.
  const bool valid = dds_stream_normalize_data(reinterpret_cast<char*>(scratch_.data()), &end,
                                               static_cast<std::uint32_t>(scratch_.size()), bswap,
                                               xcdr_version, descriptor_->m_ops) != nullptr;
  AUTODRIVE_THROW_UNLESS(valid, "a serialized " << descriptor_->m_typename << " on " << topic_name_
                                                << " (" << cdr.size()
                                                << " bytes) is not a valid sample of that type");
  const std::unique_ptr<void, SampleDeleter> sample(
      std::calloc(1, descriptor_->m_size),  // NOLINT(cppcoreguidelines-no-malloc)
      SampleDeleter{descriptor_});
  AUTODRIVE_CHECK(sample != nullptr);
  dds_istream_t in;
  dds_istream_init(&in, static_cast<std::uint32_t>(scratch_.size()), scratch_.data(), xcdr_version);
  (void)dds_stream_read(&in, static_cast<char*>(sample.get()), descriptor_->m_ops);
  dds_istream_fini(&in);
  internal::ThrowIfError(dds_write(writer_.handle(), sample.get()), "dds_write");
}

}  // namespace autodrive::dds
