"""What an MCAP doctor checks of a file's order, read as a stream (no index, no sorting)."""

from __future__ import annotations


def mcap_file_order(path):
    """(channel topic, log time, sequence) of every message in the order the file holds them,
    read as a stream (no index, no sorting); a file cut short, up to its last whole chunk (the
    library's stream reader ends a cut inside a record's length with EndOfFile, inside one of
    its fields with struct.error)."""
    import struct

    from mcap.exceptions import EndOfFile
    from mcap.records import Channel, Message
    from mcap.stream_reader import StreamReader

    topics, out = {}, []
    with open(path, "rb") as f:
        try:
            for r in StreamReader(f, skip_magic=False).records:
                if isinstance(r, Channel):
                    topics[r.id] = r.topic
                elif isinstance(r, Message):
                    out.append((topics[r.channel_id], r.log_time, r.sequence))
        except (EndOfFile, struct.error):
            pass
    return out


def ordering_faults(path):
    """Messages whose log time is earlier than the one before them in the file, and channels
    whose sequence numbers are not 1, 2, 3, ...: what an MCAP doctor warns about."""
    order = mcap_file_order(path)
    backwards = sum(b[1] < a[1] for a, b in zip(order, order[1:]))
    by_topic = {}
    for topic, _, seq in order:
        by_topic.setdefault(topic, []).append(seq)
    bad_seq = [t for t, seqs in by_topic.items() if seqs != list(range(1, len(seqs) + 1))]
    return backwards, bad_seq, len(order)


def rewrite_bag(bag, out, *, order=None, data=None, chunk_size=16 * 1024) -> int:
    """Copy recording ``bag`` into the new bag directory ``out`` with the mcap library's writer:
    the same schemas, channels, metadata and messages, the messages sorted by ``order(channel,
    message)`` if given and their bytes replaced by ``data(channel, message)`` if given.
    Returns the number of messages."""
    import shutil
    from pathlib import Path

    from mcap.reader import make_reader
    from mcap.writer import CompressionType, Writer

    bag, out = Path(bag), Path(out)
    src = next(bag.glob("*.mcap"))
    out.mkdir()
    shutil.copy(bag / "metadata.yaml", out / "metadata.yaml")
    with open(src, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        msgs = [(ch, m) for _, ch, m in reader.iter_messages(log_time_order=False)]
        metadata = list(reader.iter_metadata())
    if order is not None:
        msgs.sort(key=lambda cm: order(*cm))
    with open(out / f"{out.name}_0.mcap", "wb") as f:
        w = Writer(f, chunk_size=chunk_size, compression=CompressionType.ZSTD)
        w.start(profile="ros2", library="test")
        for s in summary.schemas.values():
            w.register_schema(s.name, s.encoding, s.data)
        for c in summary.channels.values():
            w.register_channel(c.topic, c.message_encoding, c.schema_id, c.metadata)
        for m in metadata:
            w.add_metadata(m.name, m.metadata)
        for ch, m in msgs:
            payload = m.data if data is None else data(ch, m)
            w.add_message(ch.id, m.log_time, payload, m.publish_time, m.sequence)
        w.finish()
    return len(msgs)
