"""Adapter for rule weather_year: a typical year read once (railtherm.study.weather.read_weather)
for the energy jobs (write_year: they load it without importing the readers again)."""

from railtherm import logs
from railtherm.study import weather

log = logs.to_file(snakemake.log[0])
year = weather.read_weather(snakemake.input[0])
weather.write_year(year, snakemake.output[0])
log.info("%s: %d hours", year.source, year.hours)
