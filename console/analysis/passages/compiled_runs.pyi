import numpy as np

def chunk_runs(
    register_id: np.ndarray,
    time_ns: np.ndarray,
    subsecond: np.ndarray,
    value: np.ndarray,
    head_lut: np.ndarray,
    channel_lut: np.ndarray,
    wheel_lut: np.ndarray,
    keep_releases: bool,
    /,
) -> tuple[bytearray, bytearray, int, bytearray]: ...
def head_spans(
    head: np.ndarray, time_ns: np.ndarray, gap_ns: int, slot: np.ndarray, /
) -> tuple[int, bytearray, bytearray, bytearray, bytearray, bytearray] | None: ...
def merge_runs(order: np.ndarray, columns: np.ndarray, /) -> tuple[int, bytearray]: ...
def group_extremes(
    n: int, group: np.ndarray, values: np.ndarray, channel: np.ndarray, wanted: int, /
) -> tuple[bytearray, bytearray, bytearray]: ...
def squeeze_rows(rows: np.ndarray, width: int, /) -> tuple[bytes, bytearray]: ...
def bucket_rows(
    key_head: np.ndarray, key_second: np.ndarray, head: np.ndarray, time_ns: np.ndarray, /
) -> bytearray: ...
