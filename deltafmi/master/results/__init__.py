"""What a run leaves behind and shows: ``csv_file`` streams rows to a CSV result file and reads
them back (numbers formatted in C, ``native/csv_rows.c``), ``writers`` picks the writer by the
file's extension (CSV, Parquet with units, MATLAB .mat), ``progress`` draws the progress bar and
the end-of-run summary, ``plot`` draws signals of a result file."""

__all__: list[str] = []
