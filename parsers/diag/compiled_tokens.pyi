def tokenize(
    data: bytes | bytearray | memoryview, /
) -> tuple[
    int,
    bytearray,
    bytearray,
    bytearray,
    bytearray,
    bytearray,
    list[bytes],
    bytearray,
    list[bytes],
    bytearray,
    bytearray,
    bytearray,
]: ...
