"""The report: the study's figures and tables, and the audit of published values.

- :mod:`~railtherm.report.plots`: every figure (a vehicle's there, the study's in
  :mod:`~railtherm.report.studyfigures`, on :mod:`~railtherm.report.figurebase`);
- :mod:`~railtherm.report.tables`, :mod:`~railtherm.report.tableformat`: the tables (CSV and
  Markdown at stated precision);
- :mod:`~railtherm.report.audit`: the audit of the paper's published values (its checks in
  :mod:`~railtherm.report.auditclaims` and :mod:`~railtherm.report.auditvalues`, on
  :mod:`~railtherm.report.auditbase`).
"""
