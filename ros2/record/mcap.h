#pragma once
/// @file
/// MCAP files (https://mcap.dev/spec), written and read from the specification: the leading and
/// trailing magic, a Header, Schema and Channel records, Messages in uncompressed Chunks with a
/// CRC32 each and one MessageIndex per channel after each chunk, Metadata records, DataEnd with
/// the data section's CRC, a summary section (Schemas, Channels, Statistics, ChunkIndexes,
/// MetadataIndexes), SummaryOffsets and a Footer with the summary's CRC. The reader reads a
/// file by its index (footer, summary, chunk indexes) and checks every CRC; a truncated or
/// corrupt file is refused with `InputError`.

#include <cstddef>
#include <cstdint>
#include <fstream>
#include <functional>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace autodrive::ros2 {

/// CRC-32 (IEEE 802.3, zlib's) of `data`, continuing from `crc` (0 to start).
[[nodiscard]] std::uint32_t Crc32(std::span<const std::byte> data, std::uint32_t crc = 0);

using McapMetadata = std::map<std::string, std::string>;

struct McapSchema {
  std::uint16_t id = 0;
  std::string name;
  std::string encoding;
  std::string data;
};

struct McapChannel {
  std::uint16_t id = 0;
  std::uint16_t schema_id = 0;
  std::string topic;
  std::string message_encoding;
  McapMetadata metadata;
};

struct McapMessage {
  std::uint16_t channel_id = 0;
  std::uint32_t sequence = 0;
  std::uint64_t log_time = 0;      ///< ns since the epoch (rosbag2: receive time)
  std::uint64_t publish_time = 0;  ///< ns since the epoch (rosbag2: source time)
  std::vector<std::byte> data;
};

struct McapStatistics {
  std::uint64_t message_count = 0;
  std::uint16_t schema_count = 0;
  std::uint32_t channel_count = 0;
  std::uint32_t attachment_count = 0;
  std::uint32_t metadata_count = 0;
  std::uint32_t chunk_count = 0;
  std::uint64_t message_start_time = 0;
  std::uint64_t message_end_time = 0;
  std::map<std::uint16_t, std::uint64_t> channel_message_counts;
};

/// Writes one MCAP file. Schemas and channels go into the chunk being filled (before the
/// messages that use them); `Close` writes the rest. Not thread-safe; not copyable.
class McapWriter {
 public:
  struct Options {
    std::string profile = "ros2";
    std::string library = "autodrive-record";
    /// A chunk is closed once its records reach this many bytes.
    std::size_t chunk_size = std::size_t{1} << 20;
  };
  /// Creates (truncates) `path`; throws `InputError` when it cannot.
  McapWriter(const std::string& path, Options options);
  McapWriter(const McapWriter&) = delete;
  McapWriter& operator=(const McapWriter&) = delete;
  /// Closes the file if `Close` was not called (errors are swallowed).
  ~McapWriter();

  /// Returns the new schema's id (1, 2, ...).
  std::uint16_t AddSchema(const std::string& name, const std::string& encoding,
                          const std::string& data);
  /// Returns the new channel's id (0, 1, ...).
  std::uint16_t AddChannel(std::uint16_t schema_id, const std::string& topic,
                           const std::string& message_encoding, const McapMetadata& metadata);
  void WriteMessage(std::uint16_t channel_id, std::uint32_t sequence, std::uint64_t log_time,
                    std::uint64_t publish_time, std::span<const std::byte> data);
  /// A Metadata record (in the data section, indexed in the summary).
  void WriteMetadata(const std::string& name, const McapMetadata& metadata);
  /// Ends the data section and writes the summary and footer. Throws `InputError` when the file
  /// cannot be written. Idempotent.
  void Close();

  [[nodiscard]] const McapStatistics& statistics() const { return statistics_; }
  [[nodiscard]] std::uint64_t bytes_written() const { return offset_; }

 private:
  struct ChunkIndex {
    std::uint64_t message_start_time = 0;
    std::uint64_t message_end_time = 0;
    std::uint64_t chunk_start_offset = 0;
    std::uint64_t chunk_length = 0;
    std::map<std::uint16_t, std::uint64_t> message_index_offsets;
    std::uint64_t message_index_length = 0;
    std::uint64_t uncompressed_size = 0;
  };
  struct MetadataIndex {
    std::uint64_t offset = 0;
    std::uint64_t length = 0;
    std::string name;
  };
  /// Writes `bytes`; part of the data section's CRC when `data_section` (`crc`: theirs, when
  /// known).
  void Emit(std::span<const std::byte> bytes, bool data_section,
            std::optional<std::uint32_t> crc = std::nullopt);
  void FlushChunk();

  Options options_;
  std::ofstream out_;
  std::string path_;
  bool closed_ = false;
  std::uint64_t offset_ = 0;
  std::uint32_t data_crc_ = 0;
  std::vector<McapSchema> schemas_;
  std::vector<McapChannel> channels_;
  std::vector<std::byte> chunk_;  // the open chunk's records
  std::uint64_t chunk_start_time_ = 0;
  std::uint64_t chunk_end_time_ = 0;
  bool chunk_has_messages_ = false;
  std::map<std::uint16_t, std::vector<std::pair<std::uint64_t, std::uint64_t>>> chunk_index_;
  std::vector<ChunkIndex> chunk_indexes_;
  std::vector<MetadataIndex> metadata_indexes_;
  McapStatistics statistics_;
};

/// Reads an MCAP file through its index: the footer, the summary and each chunk. The
/// constructor reads the summary and checks the footer's summary CRC and the data section's CRC;
/// `ReadMessages` checks each chunk's CRC. Throws `InputError` naming what is wrong on a file
/// that is not MCAP, is truncated, is corrupt or has no summary.
class McapReader {
 public:
  explicit McapReader(const std::string& path);

  [[nodiscard]] const std::string& profile() const { return profile_; }
  [[nodiscard]] const std::string& library() const { return library_; }
  [[nodiscard]] const std::map<std::uint16_t, McapSchema>& schemas() const { return schemas_; }
  [[nodiscard]] const std::map<std::uint16_t, McapChannel>& channels() const { return channels_; }
  /// Every field zero when the file has no Statistics record.
  [[nodiscard]] const McapStatistics& statistics() const { return statistics_; }
  [[nodiscard]] bool has_statistics() const { return has_statistics_; }
  /// The Metadata records by name (read through the MetadataIndexes).
  [[nodiscard]] const std::map<std::string, McapMetadata>& metadata() const { return metadata_; }

  /// Calls `on_message` for every message, chunk by chunk in the order of the chunks' start
  /// times, each chunk's messages by log time.
  void ReadMessages(const std::function<void(const McapMessage&)>& on_message);

 private:
  struct Chunk {
    std::uint64_t message_start_time = 0;
    std::uint64_t offset = 0;
    std::uint64_t length = 0;
  };
  std::vector<std::byte> ReadAt(std::uint64_t offset, std::uint64_t length);

  std::string path_;
  std::ifstream in_;
  std::uint64_t size_ = 0;
  std::string profile_;
  std::string library_;
  std::map<std::uint16_t, McapSchema> schemas_;
  std::map<std::uint16_t, McapChannel> channels_;
  McapStatistics statistics_;
  bool has_statistics_ = false;
  std::map<std::string, McapMetadata> metadata_;
  std::vector<Chunk> chunks_;
};

}  // namespace autodrive::ros2
