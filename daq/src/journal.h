// The recorder's journal (private to daq, docs/recording.md "Journal format"): a 16-byte header,
// then records [u32 payload size][u16 type][u16 0][payload][u32 CRC-32 of all before it].
// Little-endian. Append-only, so a crash can only tear the last record; the reader stops at the
// first record that is incomplete or fails its CRC.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "strut/daq/recorder.h"

namespace strut::daq::journal {

inline constexpr char kMagic[8] = {'S', 'T', 'R', 'U', 'T', 'J', 'N', 'L'};
inline constexpr std::uint32_t kVersion = 1;
inline constexpr std::size_t kHeaderBytes = 16;
inline constexpr std::size_t kRecordOverhead = 12;  //!< size, type, padding, CRC
//! Larger payloads are taken for damage (a block of 4 channels at 50 kHz for 10 s is 30 MB).
inline constexpr std::uint32_t kMaxPayload = 1u << 30;

enum class RecordType : std::uint16_t {
  kOpen = 1,   //!< JSON: root metadata, first clock pair
  kBegin = 2,  //!< JSON: experiment descriptor
  kBlock = 3,  //!< binary samples of the open experiment
  kEvent = 4,  //!< JSON: monotonic_ns, kind, text
  kEnd = 5,    //!< JSON: status, periods
  kClock = 6,  //!< JSON: monotonic_ns, utc_ns
  kClose = 7,  //!< JSON: closed_utc
  kResume = 8,  //!< JSON: monotonic_ns, utc_ns, resumed_utc, text: the recording goes on after a Close or a cut
  kGroup = 9,   //!< JSON: a root metadata group, merged into one of that name
};

//! CRC-32 (IEEE 802.3, the zlib one), continued from `crc` (0 to start).
std::uint32_t Crc32(std::span<const std::byte> bytes, std::uint32_t crc = 0);

//! The 16 header bytes.
std::vector<std::byte> Header();

//! A whole record of `type` around `payload`.
std::vector<std::byte> Record(RecordType type, std::span<const std::byte> payload);
std::vector<std::byte> Record(RecordType type, const std::string& json);

//! Payloads.
std::string OpenPayload(const RecordingMetadata& metadata, const std::string& created_utc,
                        std::int64_t monotonic_ns, std::int64_t utc_ns);
std::string BeginPayload(const ExperimentDescriptor& descriptor);
//! A Block record built directly (one copy of the samples).
std::vector<std::byte> BlockRecord(const SampleBlock& block);
std::string EventPayload(std::int64_t monotonic_ns, std::string_view kind, std::string_view text);
std::string EndPayload(EndStatus status, long periods);
std::string ClockPayload(std::int64_t monotonic_ns, std::int64_t utc_ns);
std::string ClosePayload(const std::string& closed_utc);
std::string ResumePayload(std::int64_t monotonic_ns, std::int64_t utc_ns, const std::string& resumed_utc,
                          const std::string& text);
std::string GroupPayload(const MetadataGroup& group);

//! Now on CLOCK_MONOTONIC and CLOCK_REALTIME, ns.
std::int64_t MonotonicNowNs();
std::int64_t UtcNowNs();
//! ISO 8601 UTC with milliseconds ("2026-12-02T04:44:35.123Z").
std::string Iso8601Ms(std::int64_t utc_ns);

}  // namespace strut::daq::journal
