"""MCAP rosbag2 bags of SMM runs: writer, reader, repair, info, recorder and replay (``smm-bag``)."""

from smm_bag.errors import (
    BagError,
    BagExistsError,
    CorruptBagError,
    MissingTopicsError,
    NotABagError,
    TruncatedBagError,
    UnknownTypeError,
    WriterStateError,
)
from smm_bag.metadata import BagMetadata, FileInfo, TopicInfo, read_metadata
from smm_bag.qos import QosProfile
from smm_bag.reader import BagMessage, BagReader
from smm_bag.writer import BagWriter, WriterOptions

__all__ = [
    "BagError",
    "BagExistsError",
    "BagMessage",
    "BagMetadata",
    "BagReader",
    "BagWriter",
    "CorruptBagError",
    "FileInfo",
    "MissingTopicsError",
    "NotABagError",
    "QosProfile",
    "TopicInfo",
    "TruncatedBagError",
    "UnknownTypeError",
    "WriterOptions",
    "WriterStateError",
    "read_metadata",
]
