"""Facts worked out from files, kept while the files are unchanged: ``GET /maps`` parses a map once.

A file's version is its (mtime_ns, size, inode): a save renames a new file into place (a new
inode), an edit in place changes the time or the size. A value is worked out again when the
file it came from, or one of the files it also read (the map's image), has another version.
Working out holds the cache's lock, so requests arriving together parse a file once, and the
caller learns whether the value is new (to log a broken map once per version, not per
request). Pure.
"""

import os
import threading


def file_key(path):
    """The version of the file at ``path`` now (None when it cannot be stat'ed)."""
    try:
        info = os.stat(path)
    except OSError:
        return None
    return info.st_mtime_ns, info.st_size, info.st_ino


class FileVersionCache:
    """``{path: value}`` of the version each value was worked out from."""

    def __init__(self):
        self._lock = threading.Lock()
        self._entries = {}  # path -> (other paths, their keys with path's first, value)

    def get(self, path, work):
        """``(value, new)``: ``work()`` → ``(value, other_paths)`` runs only when a file changed."""
        with self._lock:
            entry = self._entries.get(path)
            if entry is not None and entry[1] == _keys(path, entry[0]):
                return entry[2], False
            key = file_key(path)  # before reading: an edit meanwhile is read again next time
            value, others = work()
            self._entries[path] = (tuple(others), (key,) + tuple(file_key(p) for p in others), value)
            return value, True

    def keep_only(self, paths):
        """Forget the values of files not in ``paths`` (deleted or renamed maps)."""
        keep = set(paths)
        with self._lock:
            for path in [p for p in self._entries if p not in keep]:
                del self._entries[path]


def _keys(path, others):
    return (file_key(path),) + tuple(file_key(p) for p in others)
