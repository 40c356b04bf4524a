"""STS packets cut from a byte stream as a servo listens: whole packets in order however the bytes come, and
anything else skipped or dropped and counted, never an exception."""

from hypothesis import given, settings
from hypothesis import strategies as st

from robots.feetech.control_table import BY_NAME, Register, from_register, to_register
from robots.feetech.packets import Instruction, Packet, PacketReader, packet


def test_a_packet_comes_out_whole_however_its_bytes_arrive():
    sent = packet(3, Instruction.WRITE, bytes([42, 0x00, 0x08]))
    assert sent == bytes([0xFF, 0xFF, 3, 5, 3, 42, 0x00, 0x08, (~(3 + 5 + 3 + 42 + 8)) & 0xFF])
    reader = PacketReader()
    got = [p for byte in sent for p in reader.feed(bytes([byte]))]
    assert got == [Packet(3, Instruction.WRITE, bytes([42, 0, 8]))] and reader.corrupt == 0


def test_a_wrong_checksum_is_dropped_and_counted_and_the_next_packet_still_read():
    bad = bytearray(packet(1, Instruction.PING))
    bad[-1] ^= 0x5A
    reader = PacketReader()
    assert reader.feed(bytes(bad) + packet(2, Instruction.PING)) == [Packet(2, Instruction.PING, b"")]
    assert reader.corrupt == 1


@settings(max_examples=300, deadline=None)
@given(junk=st.binary(max_size=80).map(lambda b: b.replace(b"\xff", b"")), ids=st.lists(st.integers(0, 0xFE)))
def test_junk_before_packets_is_skipped_and_counted(junk, ids):
    reader = PacketReader()
    got = reader.feed(junk + b"".join(packet(i, Instruction.PING) for i in ids))
    assert [p.servo_id for p in got] == ids and reader.skipped_bytes == len(junk)


@settings(max_examples=300, deadline=None)
@given(st.lists(st.binary(max_size=40), max_size=8))
def test_any_bytes_at_all_never_raise(chunks):
    reader = PacketReader()
    for chunk in chunks:
        for p in reader.feed(chunk):
            assert 0 <= p.servo_id <= 0xFE and len(p.params) <= 248


@given(st.integers(-2047, 2047))
def test_a_signed_register_holds_sign_and_magnitude(value):
    offset: Register = BY_NAME["Homing_Offset"]
    raw = to_register(value, offset)
    assert raw < 1 << 12 and from_register(raw, offset) == value
    assert (raw >> 11) == (value < 0)
