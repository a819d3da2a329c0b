"""What an MCAP doctor checks of a file's order, read as a stream (no index, no sorting)."""

from __future__ import annotations


def mcap_file_order(path):
    """(channel topic, log time, sequence) of every message in the order the file holds them,
    read as a stream (no index, no sorting); a file cut short, up to its last whole chunk."""
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
        except EndOfFile:
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
