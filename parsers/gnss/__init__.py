"""GNSS telemetry by format: receiver streams (NMEA, gpsd JSON, binary packets), device exports, GPX,
monitoring-centre tables, the head/end-of-train units' LoRaWAN payload; all give the one fix table."""
