"""A CSV table's text as cells, bounded in memory and time (`pamd.client.training_tables` turns
them into named columns): read a line at a time (at most `MAX_LINE_CHARS` each, never
the whole file at once), the header's columns at most `MAX_COLUMNS`, the cells at most
`MAX_CELLS`, handed over in chunks of about `CHUNK_CELLS` cells, transposed to
columns. '#' lines and blank lines before the header are skipped; ',' ';' and tab
separate cells (sniffed on the first lines, at most `SNIFF_CHARS` of them). Every
refusal names file:line."""

from __future__ import annotations

import _csv
import csv
import gc
from collections.abc import Iterator
from dataclasses import dataclass
from typing import TextIO

from pamd.client.table_checks import MAX_CELLS, MAX_COLUMNS, MAX_LINE_CHARS, shown
from pamd.wire.errors import ModelError

#: Cells handed over per chunk (rows = this / columns).
CHUNK_CELLS = 1 << 20
#: Characters the separator is sniffed on.
SNIFF_CHARS = 64 << 10
#: Characters read at a time (split into lines in C).
BLOCK_CHARS = 4 << 20


@dataclass
class Chunk:
    """Some data rows: each one's file line, and the cells by column (as many as the
    header has: a short row's missing cells are '', a long row's extra ones dropped)."""

    lines: list[int]
    columns: list[tuple[str, ...]]


class CsvText:
    """One CSV file opened for reading: its header, then its rows in chunks."""

    def __init__(self, path: str) -> None:
        self.path = path
        self.where = shown(path)
        try:
            self._fh: TextIO = open(path, newline="", encoding="utf-8-sig")  # noqa: SIM115
        except OSError as exc:
            raise ModelError(f"{self.where}: cannot read it as a CSV text file ({exc})"
                             ) from None
        self.line_no = 0
        self._ahead: list[str] = []
        try:
            self.header_line, first = self._header()
            self.dialect = self._sniff(first)
            self.header = next(csv.reader([first], self.dialect))  # as written: `shown`
        except BaseException:
            self._fh.close()
            raise
        if len(self.header) > MAX_COLUMNS:
            self._fh.close()
            raise ModelError(f"{self.where}:{self.header_line}: {len(self.header)} columns, "
                             f"more than a table may have ({MAX_COLUMNS})")

    def close(self) -> None:
        self._fh.close()

    def __enter__(self) -> CsvText:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _line(self) -> str | None:
        """The next line without its end (None at the end), at most MAX_LINE_CHARS."""
        text = self._ahead.pop(0) if self._ahead else self._read()
        if not text:
            return None
        self.line_no += 1
        if len(text) > MAX_LINE_CHARS and not text.endswith(("\n", "\r")):
            raise ModelError(f"{self.where}:{self.line_no}: a line longer than "
                             f"{MAX_LINE_CHARS} characters: not a table pamd reads")
        return text.rstrip("\r\n")

    def _read(self) -> str:
        try:
            return self._fh.readline(MAX_LINE_CHARS + 1)
        except UnicodeDecodeError as exc:
            raise ModelError(f"{self.where}:{self.line_no + 1 + len(self._ahead)}: not UTF-8 "
                             f"text ({exc.reason})") from None
        except OSError as exc:
            raise ModelError(f"{self.where}: cannot read it ({exc})") from None

    def _header(self) -> tuple[int, str]:
        while True:
            text = self._line()
            if text is None:
                raise ModelError(f"{self.where}: empty file (no header row)")
            if text.strip() and not text.lstrip().startswith("#"):
                return self.line_no, text

    def _sniff(self, header: str) -> type[csv.Dialect] | csv.Dialect:
        """The separator, from the header and the lines after it (kept to be read)."""
        sample, size = [header], len(header)
        while len(sample) < 20 and size < SNIFF_CHARS:
            try:
                text = self._read()
            except ModelError:
                break  # said with its line when it is read
            if not text:
                break
            self._ahead.append(text)
            sample.append(text[:SNIFF_CHARS].rstrip("\r\n"))
            size += len(text)
        try:
            return csv.Sniffer().sniff("\n".join(sample)[:SNIFF_CHARS], delimiters=",;\t")
        except csv.Error:
            return csv.excel

    def _source(self) -> Iterator[str]:
        """The lines after the header: those the sniff read ahead, then the rest of the
        file a block at a time (split in C), each at most MAX_LINE_CHARS."""
        n = self.header_line
        for text in self._ahead:
            n += 1
            self._check_length(text, n)
            yield text
        self._ahead = []
        pending = ""
        while True:
            try:
                block = self._fh.read(BLOCK_CHARS)
            except UnicodeDecodeError as exc:
                raise ModelError(f"{self.where}: not UTF-8 text after line {n} "
                                 f"({exc.reason})") from None
            if not block:
                break
            lines = (pending + block).splitlines(keepends=True)
            pending = lines.pop() if lines and not lines[-1].endswith("\n") else ""
            if lines and max(map(len, lines)) > MAX_LINE_CHARS + 2:
                for k, text in enumerate(lines):
                    self._check_length(text.rstrip("\r\n"), n + k + 1)
            self._check_length(pending, n + len(lines) + 1)
            n += len(lines)
            yield from lines
        if pending:
            yield pending

    def _check_length(self, text: str, line: int) -> None:
        if len(text) > MAX_LINE_CHARS:
            raise ModelError(f"{self.where}:{line}: a line longer than {MAX_LINE_CHARS} "
                             "characters: not a table pamd reads")

    def chunks(self) -> Iterator[Chunk]:
        """The data rows that hold a cell, `CHUNK_CELLS` cells at a time, by column;
        each row's file line (the csv reader's count of the lines it read)."""
        width = len(self.header)
        per_chunk = max(1, CHUNK_CELLS // max(width, 1))
        limit_rows = MAX_CELLS // max(width, 1)
        reader = csv.reader(self._source(), self.dialect)
        count = 0
        while True:
            collect = gc.isenabled()  # a chunk's rows are lists of text, never cyclic, and
            gc.disable()  # gone once transposed: the collector's passes over them were
            try:  # two thirds of the read
                lines, columns = self._chunk(reader, width, per_chunk)
            finally:
                if collect:
                    gc.enable()
            if not lines:
                return
            count += len(lines)
            if count > limit_rows:
                line = lines[len(lines) - (count - limit_rows)]
                raise ModelError(f"{self.where}:{line}: more than {MAX_CELLS} cells "
                                 f"({width} columns): more than a training table may hold; "
                                 "record long runs as MCAP (pamd run --record) or split "
                                 "the table")
            yield Chunk(lines, columns)

    def _chunk(self, reader: _csv.Reader, width: int, size: int
               ) -> tuple[list[int], list[tuple[str, ...]]]:
        """Up to `size` rows that hold a cell, transposed: (their lines, the columns)."""
        lines: list[int] = []
        rows: list[list[str]] = []
        try:
            for row in reader:
                if not row or not "".join(row).strip():
                    continue
                if len(row) != width:
                    row = (row + [""] * width)[:width]
                lines.append(self.header_line + reader.line_num)
                rows.append(row)
                if len(rows) == size:
                    break
        except csv.Error as exc:
            raise ModelError(f"{self.where}:{self.header_line + reader.line_num}: {exc}"
                             ) from None
        return lines, list(zip(*rows, strict=True))
