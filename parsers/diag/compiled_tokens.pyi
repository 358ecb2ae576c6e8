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
def gather_records(
    reg_lut: object,
    reg_idx: object,
    val_idx: object,
    val_cols: object,
    val_ok: object,
    time_ok: object,
    tod_ns: object,
    subsecond: object,
    fast: object,
    /,
) -> tuple[int, bytearray, bytearray, bytearray, bytearray, bytearray, bytearray, bytearray, bytearray]: ...
