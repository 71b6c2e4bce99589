"""The data: what a lab wrote, read as it is and brought onto one time axis in SI units.

- :mod:`~railtherm.data.readers`: tables of every format (CSV, Excel, MATLAB, R, Parquet, ...);
- :mod:`~railtherm.data.rawfile`: a raw file's layout, columns and digest;
- :mod:`~railtherm.data.timeaxis`: time formats, time zones and the uniform grid;
- :mod:`~railtherm.data.units`: temperature and power units, and their contradictions;
- :mod:`~railtherm.data.ingest`: raw files -> the tidy experiment table (T, T_veh, T_o, Q_H);
- :mod:`~railtherm.data.datacheck`: the values of a study's records, checked before any fit;
- :mod:`~railtherm.data.starter`: a vehicle file written from a raw file (``railtherm
new-vehicle``).
"""
