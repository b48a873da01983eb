#include "ros2/record/mcap.h"

#include <zlib.h>

#include <algorithm>
#include <array>
#include <cstring>
#include <string_view>

#include "common/error.h"

namespace autodrive::ros2 {

namespace {

constexpr std::array<std::uint8_t, 8> kMagic = {0x89, 'M', 'C', 'A', 'P', '0', '\r', '\n'};

enum Op : std::uint8_t {
  kHeader = 0x01,
  kFooter = 0x02,
  kSchema = 0x03,
  kChannel = 0x04,
  kMessage = 0x05,
  kChunk = 0x06,
  kMessageIndex = 0x07,
  kChunkIndex = 0x08,
  kStatistics = 0x0B,
  kMetadata = 0x0C,
  kMetadataIndex = 0x0D,
  kSummaryOffset = 0x0E,
  kDataEnd = 0x0F,
};

/// opcode + length + footer fields (summary_start, summary_offset_start, summary_crc).
constexpr std::uint64_t kFooterRecordSize = 1 + 8 + 8 + 8 + 4;

/// Little-endian record content.
class Buffer {
 public:
  void U8(std::uint8_t v) { bytes_.push_back(std::byte{v}); }
  void U16(std::uint16_t v) { Int(v, 2); }
  void U32(std::uint32_t v) { Int(v, 4); }
  void U64(std::uint64_t v) { Int(v, 8); }
  void Raw(std::span<const std::byte> b) { bytes_.insert(bytes_.end(), b.begin(), b.end()); }
  void Raw(std::string_view s) { Raw(std::as_bytes(std::span(s.data(), s.size()))); }
  void Str(std::string_view s) {
    U32(static_cast<std::uint32_t>(s.size()));
    Raw(s);
  }
  void Map(const McapMetadata& m) {
    Buffer entries;
    for (const auto& [k, v] : m) {
      entries.Str(k);
      entries.Str(v);
    }
    U32(static_cast<std::uint32_t>(entries.size()));
    Raw(entries.bytes());
  }
  /// Map<uint16, uint64> (Statistics' counts, ChunkIndex's message index offsets).
  void Map(const std::map<std::uint16_t, std::uint64_t>& m) {
    Buffer entries;
    for (const auto& [k, v] : m) {
      entries.U16(k);
      entries.U64(v);
    }
    U32(static_cast<std::uint32_t>(entries.size()));
    Raw(entries.bytes());
  }
  [[nodiscard]] std::size_t size() const { return bytes_.size(); }
  [[nodiscard]] const std::vector<std::byte>& bytes() const { return bytes_; }

 private:
  void Int(std::uint64_t v, int n) {
    for (int i = 0; i < n; ++i) bytes_.push_back(static_cast<std::byte>((v >> (8 * i)) & 0xFFU));
  }
  std::vector<std::byte> bytes_;
};

/// One record: opcode, length, content.
std::vector<std::byte> Record(Op op, const Buffer& content) {
  Buffer r;
  r.U8(op);
  r.U64(content.size());
  r.Raw(content.bytes());
  return r.bytes();
}

/// Reads little-endian fields from a span; throws `InputError` naming `what` past its end.
class Cursor {
 public:
  Cursor(std::span<const std::byte> bytes, std::string what)
      : bytes_(bytes), what_(std::move(what)) {}
  std::uint8_t U8() { return static_cast<std::uint8_t>(Int(1)); }
  std::uint16_t U16() { return static_cast<std::uint16_t>(Int(2)); }
  std::uint32_t U32() { return static_cast<std::uint32_t>(Int(4)); }
  std::uint64_t U64() { return Int(8); }
  std::span<const std::byte> Take(std::uint64_t n) {
    AUTODRIVE_THROW_UNLESS(n <= remaining(), what_ << ": record truncated (needs " << n
                                                   << " bytes, " << remaining() << " left)");
    auto out = bytes_.subspan(pos_, static_cast<std::size_t>(n));
    pos_ += static_cast<std::size_t>(n);
    return out;
  }
  std::string Str() {
    auto b = Take(U32());
    return std::string(reinterpret_cast<const char*>(b.data()), b.size());
  }
  McapMetadata Map() {
    Cursor entries(Take(U32()), what_);
    McapMetadata m;
    while (entries.remaining() > 0) {
      std::string k = entries.Str();
      m[k] = entries.Str();
    }
    return m;
  }
  [[nodiscard]] std::uint64_t remaining() const { return bytes_.size() - pos_; }
  [[nodiscard]] std::size_t position() const { return pos_; }

 private:
  std::uint64_t Int(int n) {
    auto b = Take(static_cast<std::uint64_t>(n));
    std::uint64_t v = 0;
    for (int i = 0; i < n; ++i) {
      v |= static_cast<std::uint64_t>(std::to_integer<std::uint8_t>(b[static_cast<std::size_t>(i)]))
           << (8 * i);
    }
    return v;
  }
  std::span<const std::byte> bytes_;
  std::string what_;
  std::size_t pos_ = 0;
};

Buffer SchemaContent(const McapSchema& s) {
  Buffer b;
  b.U16(s.id);
  b.Str(s.name);
  b.Str(s.encoding);
  b.Str(s.data);  // uint32-prefixed bytes
  return b;
}

Buffer ChannelContent(const McapChannel& c) {
  Buffer b;
  b.U16(c.id);
  b.U16(c.schema_id);
  b.Str(c.topic);
  b.Str(c.message_encoding);
  b.Map(c.metadata);
  return b;
}

McapSchema ParseSchema(Cursor& c) {
  McapSchema s;
  s.id = c.U16();
  s.name = c.Str();
  s.encoding = c.Str();
  s.data = c.Str();
  return s;
}

McapChannel ParseChannel(Cursor& c) {
  McapChannel ch;
  ch.id = c.U16();
  ch.schema_id = c.U16();
  ch.topic = c.Str();
  ch.message_encoding = c.Str();
  ch.metadata = c.Map();
  return ch;
}

}  // namespace

std::uint32_t Crc32(std::span<const std::byte> data, std::uint32_t crc) {
  // zlib's CRC-32 is MCAP's (IEEE 802.3, reflected), and several times faster than a byte table:
  // a camera topic is about 90 MB a second, and each byte is summed once for its chunk.
  return static_cast<std::uint32_t>(
      crc32_z(crc, reinterpret_cast<const Bytef*>(data.data()), data.size()));
}

// --- Writer -----------------------------------------------------------------------------------

McapWriter::McapWriter(const std::string& path, Options options)
    : options_(std::move(options)), out_(path, std::ios::binary | std::ios::trunc), path_(path) {
  AUTODRIVE_THROW_UNLESS(out_.is_open(), "cannot create " << path);
  Emit(std::as_bytes(std::span(kMagic)), true);
  Buffer header;
  header.Str(options_.profile);
  header.Str(options_.library);
  Emit(Record(kHeader, header), true);
}

McapWriter::~McapWriter() {
  try {
    Close();
  } catch (...) {  // NOLINT(bugprone-empty-catch): a destructor must not throw
  }
}

void McapWriter::Emit(std::span<const std::byte> bytes, bool data_section,
                      std::optional<std::uint32_t> crc) {
  out_.write(reinterpret_cast<const char*>(bytes.data()),
             static_cast<std::streamsize>(bytes.size()));
  AUTODRIVE_THROW_UNLESS(out_.good(), "cannot write " << path_);
  if (data_section) {
    // Bytes whose CRC is known already (a chunk's records) are not summed again.
    data_crc_ = crc ? static_cast<std::uint32_t>(
                          crc32_combine(data_crc_, *crc, static_cast<z_off_t>(bytes.size())))
                    : Crc32(bytes, data_crc_);
  }
  offset_ += bytes.size();
}

std::uint16_t McapWriter::AddSchema(const std::string& name, const std::string& encoding,
                                    const std::string& data) {
  McapSchema s{static_cast<std::uint16_t>(schemas_.size() + 1), name, encoding, data};
  const auto record = Record(kSchema, SchemaContent(s));
  chunk_.insert(chunk_.end(), record.begin(), record.end());
  schemas_.push_back(std::move(s));
  return schemas_.back().id;
}

std::uint16_t McapWriter::AddChannel(std::uint16_t schema_id, const std::string& topic,
                                     const std::string& message_encoding,
                                     const McapMetadata& metadata) {
  McapChannel c{static_cast<std::uint16_t>(channels_.size()), schema_id, topic, message_encoding,
                metadata};
  const auto record = Record(kChannel, ChannelContent(c));
  chunk_.insert(chunk_.end(), record.begin(), record.end());
  statistics_.channel_message_counts[c.id] = 0;
  channels_.push_back(std::move(c));
  return channels_.back().id;
}

void McapWriter::WriteMessage(std::uint16_t channel_id, std::uint32_t sequence,
                              std::uint64_t log_time, std::uint64_t publish_time,
                              std::span<const std::byte> data) {
  AUTODRIVE_CHECK(channel_id < channels_.size(), "unknown channel " << channel_id);
  chunk_index_[channel_id].emplace_back(log_time, chunk_.size());
  // The record straight into the chunk: its head, then the payload, copied once.
  Buffer head;
  head.U8(kMessage);
  head.U64(2 + 4 + 8 + 8 + data.size());
  head.U16(channel_id);
  head.U32(sequence);
  head.U64(log_time);
  head.U64(publish_time);
  chunk_.insert(chunk_.end(), head.bytes().begin(), head.bytes().end());
  chunk_.insert(chunk_.end(), data.begin(), data.end());
  if (!chunk_has_messages_) {
    chunk_start_time_ = chunk_end_time_ = log_time;
    chunk_has_messages_ = true;
  }
  chunk_start_time_ = std::min(chunk_start_time_, log_time);
  chunk_end_time_ = std::max(chunk_end_time_, log_time);
  if (statistics_.message_count == 0) {
    statistics_.message_start_time = statistics_.message_end_time = log_time;
  }
  statistics_.message_start_time = std::min(statistics_.message_start_time, log_time);
  statistics_.message_end_time = std::max(statistics_.message_end_time, log_time);
  ++statistics_.message_count;
  ++statistics_.channel_message_counts[channel_id];
  if (chunk_.size() >= options_.chunk_size) FlushChunk();
}

void McapWriter::FlushChunk() {
  if (chunk_.empty()) return;
  ChunkIndex index;
  index.message_start_time = chunk_has_messages_ ? chunk_start_time_ : 0;
  index.message_end_time = chunk_has_messages_ ? chunk_end_time_ : 0;
  index.chunk_start_offset = offset_;
  index.uncompressed_size = chunk_.size();
  // The record's head, then the records as they are (not copied into one record first).
  const std::uint32_t crc = Crc32(chunk_);
  Buffer c;
  c.U64(index.message_start_time);
  c.U64(index.message_end_time);
  c.U64(chunk_.size());
  c.U32(crc);
  c.Str("");  // no compression
  c.U64(chunk_.size());
  Buffer head;
  head.U8(kChunk);
  head.U64(c.size() + chunk_.size());
  head.Raw(c.bytes());
  index.chunk_length = head.size() + chunk_.size();
  Emit(head.bytes(), true);
  Emit(chunk_, true, crc);
  const std::uint64_t indexes_start = offset_;
  for (const auto& [channel, entries] : chunk_index_) {
    Buffer mi;
    mi.U16(channel);
    mi.U32(static_cast<std::uint32_t>(entries.size() * 16));
    for (const auto& [time, at] : entries) {
      mi.U64(time);
      mi.U64(at);
    }
    index.message_index_offsets[channel] = offset_;
    Emit(Record(kMessageIndex, mi), true);
  }
  index.message_index_length = offset_ - indexes_start;
  chunk_indexes_.push_back(std::move(index));
  ++statistics_.chunk_count;
  chunk_.clear();
  chunk_index_.clear();
  chunk_has_messages_ = false;
}

void McapWriter::WriteMetadata(const std::string& name, const McapMetadata& metadata) {
  FlushChunk();
  Buffer m;
  m.Str(name);
  m.Map(metadata);
  const auto record = Record(kMetadata, m);
  metadata_indexes_.push_back({offset_, record.size(), name});
  Emit(record, true);
  ++statistics_.metadata_count;
}

void McapWriter::Close() {
  if (closed_) return;
  closed_ = true;
  FlushChunk();
  {
    Buffer end;
    end.U32(data_crc_);
    Emit(Record(kDataEnd, end), false);
  }
  const std::uint64_t summary_start = offset_;
  std::uint32_t summary_crc = 0;
  struct Group {
    Op op = kSchema;
    std::uint64_t start = 0;
    std::uint64_t length = 0;
  };
  std::vector<Group> groups;
  auto emit_summary = [&](const std::vector<std::byte>& record) {
    summary_crc = Crc32(record, summary_crc);
    Emit(record, false);
  };
  // Writes `records` as one group of the summary (remembered for its SummaryOffset), then
  // empties it for the next group.
  auto group = [&](Op op, std::vector<std::vector<std::byte>>& records) {
    if (records.empty()) return;
    Group g{op, offset_, 0};
    for (const auto& r : records) emit_summary(r);
    g.length = offset_ - g.start;
    groups.push_back(g);
    records.clear();
  };
  std::vector<std::vector<std::byte>> records;
  for (const auto& s : schemas_) records.push_back(Record(kSchema, SchemaContent(s)));
  group(kSchema, records);
  for (const auto& c : channels_) records.push_back(Record(kChannel, ChannelContent(c)));
  group(kChannel, records);
  {
    statistics_.schema_count = static_cast<std::uint16_t>(schemas_.size());
    statistics_.channel_count = static_cast<std::uint32_t>(channels_.size());
    Buffer s;
    s.U64(statistics_.message_count);
    s.U16(statistics_.schema_count);
    s.U32(statistics_.channel_count);
    s.U32(statistics_.attachment_count);
    s.U32(statistics_.metadata_count);
    s.U32(statistics_.chunk_count);
    s.U64(statistics_.message_start_time);
    s.U64(statistics_.message_end_time);
    s.Map(statistics_.channel_message_counts);
    records.push_back(Record(kStatistics, s));
  }
  group(kStatistics, records);
  for (const auto& m : metadata_indexes_) {
    Buffer b;
    b.U64(m.offset);
    b.U64(m.length);
    b.Str(m.name);
    records.push_back(Record(kMetadataIndex, b));
  }
  group(kMetadataIndex, records);
  for (const auto& ci : chunk_indexes_) {
    Buffer b;
    b.U64(ci.message_start_time);
    b.U64(ci.message_end_time);
    b.U64(ci.chunk_start_offset);
    b.U64(ci.chunk_length);
    b.Map(ci.message_index_offsets);
    b.U64(ci.message_index_length);
    b.Str("");
    b.U64(ci.uncompressed_size);  // compressed size: not compressed
    b.U64(ci.uncompressed_size);
    records.push_back(Record(kChunkIndex, b));
  }
  group(kChunkIndex, records);
  const std::uint64_t summary_offset_start = offset_;
  for (const auto& g : groups) {
    Buffer b;
    b.U8(g.op);
    b.U64(g.start);
    b.U64(g.length);
    emit_summary(Record(kSummaryOffset, b));
  }
  Buffer footer_head;
  footer_head.U8(kFooter);
  footer_head.U64(8 + 8 + 4);
  footer_head.U64(summary_start);
  footer_head.U64(summary_offset_start);
  summary_crc = Crc32(footer_head.bytes(), summary_crc);
  Buffer footer_tail;
  footer_tail.U32(summary_crc);
  footer_tail.Raw(std::as_bytes(std::span(kMagic)));
  Emit(footer_head.bytes(), false);
  Emit(footer_tail.bytes(), false);
  out_.flush();
  AUTODRIVE_THROW_UNLESS(out_.good(), "cannot write " << path_);
  out_.close();
}

// --- Reader -----------------------------------------------------------------------------------

McapReader::McapReader(const std::string& path) : path_(path), in_(path, std::ios::binary) {
  AUTODRIVE_THROW_UNLESS(in_.is_open(), "cannot open " << path);
  in_.seekg(0, std::ios::end);
  size_ = static_cast<std::uint64_t>(in_.tellg());
  const std::uint64_t magic_size = kMagic.size();
  AUTODRIVE_THROW_UNLESS(size_ >= magic_size, path << ": not an MCAP file (too short)");
  const auto lead = ReadAt(0, magic_size);
  AUTODRIVE_THROW_UNLESS(std::memcmp(lead.data(), kMagic.data(), kMagic.size()) == 0,
                         path << ": not an MCAP file (no leading magic)");
  AUTODRIVE_THROW_UNLESS(size_ >= 2 * magic_size + kFooterRecordSize,
                         path << ": truncated MCAP file (no footer)");
  const auto trail = ReadAt(size_ - magic_size, magic_size);
  AUTODRIVE_THROW_UNLESS(std::memcmp(trail.data(), kMagic.data(), kMagic.size()) == 0,
                         path << ": truncated MCAP file (no trailing magic: was the recording "
                                 "stopped before it closed the file?)");
  const std::uint64_t footer_offset = size_ - magic_size - kFooterRecordSize;
  const auto footer_bytes = ReadAt(footer_offset, kFooterRecordSize);
  Cursor footer(footer_bytes, path + ": footer");
  AUTODRIVE_THROW_UNLESS(footer.U8() == kFooter && footer.U64() == 20,
                         path << ": corrupt MCAP file (bad footer record)");
  const std::uint64_t summary_start = footer.U64();
  const std::uint64_t summary_offset_start = footer.U64();
  const std::uint32_t summary_crc = footer.U32();
  AUTODRIVE_THROW_UNLESS(summary_start != 0,
                         path << ": MCAP file without a summary section (not indexed)");
  AUTODRIVE_THROW_UNLESS(summary_start >= magic_size && summary_start <= footer_offset &&
                             summary_offset_start <= footer_offset &&
                             (summary_offset_start == 0 || summary_offset_start >= summary_start),
                         path << ": corrupt MCAP file (footer offsets out of range)");
  const auto summary = ReadAt(summary_start, footer_offset - summary_start);
  if (summary_crc != 0) {
    std::uint32_t crc = Crc32(summary);
    crc = Crc32(std::span(footer_bytes).first(1 + 8 + 8 + 8), crc);
    AUTODRIVE_THROW_UNLESS(crc == summary_crc, path << ": corrupt MCAP file (summary CRC " << crc
                                                    << ", expected " << summary_crc << ")");
  }
  // Header.
  {
    const auto head = ReadAt(magic_size, std::min<std::uint64_t>(size_ - magic_size, 9));
    Cursor c(head, path + ": header");
    AUTODRIVE_THROW_UNLESS(c.U8() == kHeader, path << ": corrupt MCAP file (no Header record)");
    const std::uint64_t length = c.U64();
    AUTODRIVE_THROW_UNLESS(length <= summary_start, path << ": corrupt MCAP file (Header length)");
    const auto content = ReadAt(magic_size + 9, length);
    Cursor h(content, path + ": header");
    profile_ = h.Str();
    library_ = h.Str();
  }
  // Summary records.
  std::vector<std::pair<std::string, std::pair<std::uint64_t, std::uint64_t>>> metadata_indexes;
  Cursor s(summary, path + ": summary");
  while (s.remaining() > 0) {
    const std::uint8_t op = s.U8();
    Cursor r(s.Take(s.U64()), path + ": summary record");
    switch (op) {
      case kSchema: {
        McapSchema schema = ParseSchema(r);
        schemas_[schema.id] = std::move(schema);
        break;
      }
      case kChannel: {
        McapChannel channel = ParseChannel(r);
        channels_[channel.id] = std::move(channel);
        break;
      }
      case kStatistics: {
        has_statistics_ = true;
        statistics_.message_count = r.U64();
        statistics_.schema_count = r.U16();
        statistics_.channel_count = r.U32();
        statistics_.attachment_count = r.U32();
        statistics_.metadata_count = r.U32();
        statistics_.chunk_count = r.U32();
        statistics_.message_start_time = r.U64();
        statistics_.message_end_time = r.U64();
        Cursor counts(r.Take(r.U32()), path + ": statistics");
        while (counts.remaining() > 0) {
          const std::uint16_t channel = counts.U16();
          statistics_.channel_message_counts[channel] = counts.U64();
        }
        break;
      }
      case kChunkIndex: {
        Chunk chunk;
        chunk.message_start_time = r.U64();
        (void)r.U64();
        chunk.offset = r.U64();
        chunk.length = r.U64();
        AUTODRIVE_THROW_UNLESS(
            chunk.offset < summary_start && chunk.length <= summary_start - chunk.offset,
            path << ": corrupt MCAP file (chunk index out of range)");
        chunks_.push_back(chunk);
        break;
      }
      case kMetadataIndex: {
        const std::uint64_t offset = r.U64();
        const std::uint64_t length = r.U64();
        metadata_indexes.push_back({r.Str(), {offset, length}});
        break;
      }
      default:
        break;  // SummaryOffset and records this reader does not use
    }
  }
  // The data section's CRC (DataEnd is the record just before the summary).
  {
    constexpr std::uint64_t kDataEndSize = 1 + 8 + 4;
    AUTODRIVE_THROW_UNLESS(summary_start >= magic_size + kDataEndSize,
                           path << ": corrupt MCAP file (no DataEnd)");
    const std::uint64_t data_end = summary_start - kDataEndSize;
    const auto end_bytes = ReadAt(data_end, kDataEndSize);
    Cursor d(end_bytes, path + ": data end");
    AUTODRIVE_THROW_UNLESS(d.U8() == kDataEnd && d.U64() == 4,
                           path << ": corrupt MCAP file (no DataEnd before the summary)");
    const std::uint32_t expected = d.U32();
    if (expected != 0) {
      std::uint32_t crc = 0;
      constexpr std::uint64_t kBlock = std::uint64_t{1} << 20;
      for (std::uint64_t at = 0; at < data_end; at += kBlock) {
        crc = Crc32(ReadAt(at, std::min(kBlock, data_end - at)), crc);
      }
      AUTODRIVE_THROW_UNLESS(crc == expected, path << ": corrupt MCAP file (data section CRC "
                                                   << crc << ", expected " << expected << ")");
    }
  }
  for (const auto& [name, where] : metadata_indexes) {
    AUTODRIVE_THROW_UNLESS(where.first < summary_start && where.second >= 9 &&
                               where.second <= summary_start - where.first,
                           path << ": corrupt MCAP file (metadata index out of range)");
    const auto bytes = ReadAt(where.first, where.second);
    Cursor c(bytes, path + ": metadata");
    AUTODRIVE_THROW_UNLESS(c.U8() == kMetadata, path << ": corrupt MCAP file (metadata index)");
    Cursor m(c.Take(c.U64()), path + ": metadata");
    std::string record_name = m.Str();
    metadata_[record_name] = m.Map();
  }
  std::stable_sort(chunks_.begin(), chunks_.end(), [](const Chunk& a, const Chunk& b) {
    return a.message_start_time < b.message_start_time;
  });
}

std::vector<std::byte> McapReader::ReadAt(std::uint64_t offset, std::uint64_t length) {
  AUTODRIVE_THROW_UNLESS(offset <= size_ && length <= size_ - offset,
                         path_ << ": truncated MCAP file (needs bytes " << offset << "+" << length
                               << " of " << size_ << ")");
  std::vector<std::byte> out(static_cast<std::size_t>(length));
  in_.clear();
  in_.seekg(static_cast<std::streamoff>(offset));
  in_.read(reinterpret_cast<char*>(out.data()), static_cast<std::streamsize>(length));
  AUTODRIVE_THROW_UNLESS(in_.good(), path_ << ": cannot read " << length << " bytes at " << offset);
  return out;
}

void McapReader::ReadMessages(const std::function<void(const McapMessage&)>& on_message) {
  std::vector<McapMessage> messages;
  for (const Chunk& chunk : chunks_) {
    const auto bytes = ReadAt(chunk.offset, chunk.length);
    Cursor c(bytes, path_ + ": chunk");
    AUTODRIVE_THROW_UNLESS(c.U8() == kChunk, path_ << ": corrupt MCAP file (chunk index at "
                                                   << chunk.offset << " is no chunk)");
    Cursor content(c.Take(c.U64()), path_ + ": chunk");
    (void)content.U64();
    (void)content.U64();
    const std::uint64_t uncompressed_size = content.U64();
    const std::uint32_t crc = content.U32();
    const std::string compression = content.Str();
    AUTODRIVE_THROW_UNLESS(compression.empty(),
                           path_ << ": chunk compression '" << compression << "' is not supported");
    const auto records = content.Take(content.U64());
    AUTODRIVE_THROW_UNLESS(records.size() == uncompressed_size,
                           path_ << ": corrupt MCAP file (chunk size)");
    if (crc != 0) {
      const std::uint32_t actual = Crc32(records);
      AUTODRIVE_THROW_UNLESS(actual == crc, path_ << ": corrupt MCAP file (chunk at "
                                                  << chunk.offset << ": CRC " << actual
                                                  << ", expected " << crc << ")");
    }
    messages.clear();
    Cursor r(records, path_ + ": chunk records");
    while (r.remaining() > 0) {
      const std::uint8_t op = r.U8();
      Cursor record(r.Take(r.U64()), path_ + ": chunk record");
      if (op == kMessage) {
        McapMessage m;
        m.channel_id = record.U16();
        m.sequence = record.U32();
        m.log_time = record.U64();
        m.publish_time = record.U64();
        const auto data = record.Take(record.remaining());
        m.data.assign(data.begin(), data.end());
        AUTODRIVE_THROW_UNLESS(channels_.contains(m.channel_id),
                               path_ << ": message of unknown channel " << m.channel_id);
        messages.push_back(std::move(m));
      }
    }
    std::stable_sort(
        messages.begin(), messages.end(),
        [](const McapMessage& a, const McapMessage& b) { return a.log_time < b.log_time; });
    for (const auto& m : messages) on_message(m);
  }
}

}  // namespace autodrive::ros2
