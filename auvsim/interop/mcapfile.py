"""An MCAP file of many fixed-size messages, its chunks built with numpy.

``mcap.writer.Writer.add_message`` costs about 3.2 us a message in Python (a record object,
eight small writes, the statistics and the index, per message): 2.4 s for the 760k
messages of a one-hour mission, more than the generation's 1.8 CPU s (``benchmarks/export.py``
prints both). Here the messages of a channel, all one size, are laid
out as records in one numpy array, chunks are cut from their time order and joined, and
each chunk's message indexes are arrays too; the ``mcap`` package writes every other
record (``mcap.records``: header, schemas, channels, chunks, chunk indexes, statistics,
summary offsets). Messages come in blocks of time (a minute of the mission, say), so the
memory is a block's, whatever the mission's length.

The layout is the MCAP specification's (mcap.dev/spec): the magic, a Header, the data
section (Schema and Channel records, then each Chunk followed by the Message Index records
of its channels), Data End, the summary section (Schema, Channel, Statistics and Chunk
Index records, each kind a group that a Summary Offset record points to), the Footer and
the magic. Records: "Message" (op 0x05: channel_id uint16, sequence uint32, log_time
uint64, publish_time uint64, data), "Message Index" (op 0x07: channel_id uint16, then an
array, uint32 byte length, of (log_time uint64, offset uint64) into the chunk's
uncompressed records), "Footer" (summary_crc: the CRC-32 of every byte from the start of
the summary section to the footer's summary_offset_start field, inclusive). Every record is
opcode uint8, length uint64, fields, little endian ("Records" and "Serialization").
Messages are written in log-time order, channels in turn at one time.
"""

from __future__ import annotations

import struct
import zlib
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import BinaryIO

import numpy as np

MAGIC = b"\x89MCAP0\r\n"
MESSAGE, MESSAGE_INDEX, FOOTER = 0x05, 0x07, 0x02
_MESSAGE_HEADER = 1 + 8 + 2 + 4 + 8 + 8  # opcode, length, channel, sequence, two times
CHUNK_SIZE = 1 << 20  # uncompressed bytes a chunk holds, about


@dataclass
class Topic:
    """One channel of the file.

    Attributes:
        topic: the topic name.
        schema: the name of its schema (a key of ``write_mcap``'s ``schemas``).
        metadata: the channel's metadata.
    """

    topic: str
    schema: str
    metadata: dict[str, str]


# A block of messages: (channel position, log times (n,) int64 ns in order, payloads (n, S)
# uint8, each row one message), for some of the channels.
Block = Sequence[tuple[int, np.ndarray, np.ndarray]]


def _records(channel: int, first: int, log_time: np.ndarray,
             payloads: np.ndarray) -> list[bytes]:
    """Message records of one channel (sequence numbers from ``first``), each as bytes."""
    n, size = payloads.shape
    dtype = np.dtype({"names": ["op", "length", "channel", "sequence", "log", "publish",
                                "data"],
                      "formats": ["u1", "<u8", "<u2", "<u4", "<u8", "<u8", ("u1", (size,))],
                      "offsets": [0, 1, 9, 11, 15, 23, 31],
                      "itemsize": _MESSAGE_HEADER + size})
    rec = np.empty(n, dtype=dtype)
    rec["op"] = MESSAGE
    rec["length"] = _MESSAGE_HEADER - 9 + size
    rec["channel"] = channel
    rec["sequence"] = np.arange(first, first + n)
    rec["log"] = rec["publish"] = log_time
    rec["data"] = payloads
    blob, step = rec.tobytes(), dtype.itemsize
    return [blob[i:i + step] for i in range(0, len(blob), step)]


def _message_index(channel: int, times: np.ndarray, offsets: np.ndarray) -> bytes:
    pairs = np.column_stack([times, offsets]).astype("<u8").tobytes()
    return struct.pack("<BQHI", MESSAGE_INDEX, 2 + 4 + len(pairs), channel,
                       len(pairs)) + pairs


def write_mcap(f: BinaryIO, *, profile: str, library: str,
               schemas: dict[str, tuple[str, bytes]], topics: Sequence[Topic],
               blocks: Iterable[Block], compression: str = "zstd",
               chunk_size: int = CHUNK_SIZE,
               metadata: dict[str, dict[str, str]] | None = None) -> list[int]:
    """Write an MCAP file into ``f`` (at its start), block by block, so that only one
    block's messages are in memory at a time.

    Args:
        f: a binary file open for writing.
        profile: the Header's profile (``ros2``).
        library: the Header's library.
        schemas: name -> (encoding, data) of each schema the topics name.
        topics: the channels; channel ids are their positions + 1.
        blocks: the messages, block after block in time order (no time in a block later
            than one in the next); a chunk never spans two blocks.
        compression: ``zstd``, ``lz4`` or ``none``.
        chunk_size: the uncompressed size after which a chunk is closed, bytes.
        metadata: Metadata records, name -> key/value pairs, written after the
            channels and indexed in the summary.

    Returns:
        The number of messages of each topic.
    """
    from mcap.data_stream import RecordBuilder
    from mcap.opcode import Opcode
    from mcap.records import (
        Channel,
        Chunk,
        ChunkIndex,
        DataEnd,
        Header,
        Metadata,
        MetadataIndex,
        Schema,
        Statistics,
        SummaryOffset,
    )

    compress = compressor(compression)
    builder = RecordBuilder()

    def put(*records) -> int:
        """Write the records; return the file offset of the first."""
        start = f.tell()
        for r in records:
            r.write(builder)
        f.write(builder.end())
        return start

    f.write(MAGIC)
    put(Header(profile=profile, library=library))
    schema_ids = {name: i + 1 for i, name in enumerate(schemas)}
    schema_records = [Schema(id=schema_ids[name], name=name, encoding=encoding, data=data)
                      for name, (encoding, data) in schemas.items()]
    channel_records = [Channel(id=i + 1, topic=t.topic, message_encoding="cdr",
                               metadata=t.metadata, schema_id=schema_ids[t.schema])
                       for i, t in enumerate(topics)]
    put(*schema_records, *channel_records)
    metadata_indexes = []
    for name, pairs in (metadata or {}).items():
        start = put(Metadata(name=name, metadata=dict(pairs)))
        metadata_indexes.append(MetadataIndex(offset=start, length=f.tell() - start,
                                              name=name))

    counts = [0] * len(topics)
    chunk_indexes = []
    for block in blocks:
        block = [(c, t, p) for c, t, p in block if len(t)]
        if not block:
            continue
        payloads: list[bytes] = []
        for c, t, p in block:
            payloads += _records(c + 1, counts[c], t, p)
            counts[c] += len(t)
        time = np.concatenate([t for _, t, _ in block]).astype(np.int64)
        channel = np.concatenate([np.full(len(t), c + 1) for c, t, _ in block])
        size = np.concatenate([np.full(len(t), _MESSAGE_HEADER + p.shape[1])
                               for _, t, p in block])
        order = np.lexsort((channel, time))  # time order; channels in turn at one time
        time, channel, size = time[order], channel[order], size[order]
        start = np.cumsum(size) - size
        bounds = np.flatnonzero(np.diff(start // chunk_size)) + 1
        for lo, hi in zip(np.r_[0, bounds], np.r_[bounds, len(order)], strict=True):
            data = b"".join([payloads[k] for k in order[lo:hi].tolist()])
            packed, name = compress(data)
            t = time[lo:hi]
            chunk = Chunk(compression=name, data=packed, message_start_time=int(t[0]),
                          message_end_time=int(t[-1]), uncompressed_crc=zlib.crc32(data),
                          uncompressed_size=len(data))
            chunk_start = put(chunk)
            index_start = at = f.tell()
            offsets, indexes = {}, []
            for c in np.unique(channel[lo:hi]).tolist():
                mine = channel[lo:hi] == c
                record = _message_index(c, t[mine], start[lo:hi][mine] - start[lo])
                offsets[c] = at
                at += len(record)
                indexes.append(record)
            f.write(b"".join(indexes))
            chunk_indexes.append(ChunkIndex(
                message_start_time=chunk.message_start_time,
                message_end_time=chunk.message_end_time, chunk_start_offset=chunk_start,
                chunk_length=index_start - chunk_start, message_index_offsets=offsets,
                message_index_length=at - index_start, compression=name,
                compressed_size=len(packed), uncompressed_size=len(data)))
    put(DataEnd(data_section_crc=0))

    statistics = Statistics(
        message_count=sum(counts), schema_count=len(schemas), channel_count=len(topics),
        attachment_count=0, metadata_count=len(metadata_indexes), chunk_count=len(chunk_indexes),
        message_start_time=min((c.message_start_time for c in chunk_indexes), default=0),
        message_end_time=max((c.message_end_time for c in chunk_indexes), default=0),
        channel_message_counts={i + 1: n for i, n in enumerate(counts)})
    summary_start = f.tell()
    summary = bytearray()

    def add(*records) -> tuple[int, int]:
        """Append the records to the summary; return their file offset and length."""
        for r in records:
            r.write(builder)
        data = builder.end()
        summary.extend(data)
        return summary_start + len(summary) - len(data), len(data)

    groups = []
    for opcode, records in ((Opcode.SCHEMA, schema_records), (Opcode.CHANNEL, channel_records),
                            (Opcode.STATISTICS, [statistics]),
                            (Opcode.METADATA_INDEX, metadata_indexes),
                            (Opcode.CHUNK_INDEX, chunk_indexes)):
        if records:
            begin, length = add(*records)
            groups.append(SummaryOffset(group_opcode=opcode, group_start=begin,
                                        group_length=length))
    offsets_start, _ = add(*groups)
    footer = struct.pack("<BQQQ", FOOTER, 8 + 8 + 4, summary_start, offsets_start)
    crc = zlib.crc32(footer, zlib.crc32(summary))
    f.write(bytes(summary) + footer + struct.pack("<I", crc) + MAGIC)
    return counts


def compressor(name: str):
    """The function ``data -> (compressed, the Chunk's compression name)`` of a
    compression, ``zstd``, ``lz4`` or ``none``."""
    if name == "zstd":
        import zstandard

        # Level 1, not the library's 3: on a one-hour navigator bag's data in 1 MiB pieces
        # it compressed 6.48x in 0.32 CPU s against 3's 6.50x in 0.44 s (lz4: 5.24x,
        # 0.25 s; benchmarks/export.py).
        compressor = zstandard.ZstdCompressor(level=1)
        return lambda data: (compressor.compress(data), "zstd")
    if name == "lz4":
        import lz4.frame

        return lambda data: (lz4.frame.compress(data), "lz4")
    if name == "none":
        return lambda data: (data, "")
    raise ValueError(f"compression: expected zstd, lz4 or none, got {name!r}")
