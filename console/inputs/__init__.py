"""Inputs: growing files, pipes and FIFOs, gpsd, LoRaWAN uplinks over MQTT, a CAN bus; and what a file is.

A source knows its transport, not railways.  Each one runs in its own thread
and hands *items* to one queue: raw record bytes of a followed log
(:class:`console.inputs.base.LineBlock`), GNSS fixes (``GnssFix``), CAN
frames (``CanFrame``), count frames read from a followed CAN or frame log
(``FrameRows``) and notes about itself (``SourceNote``).  The live engine
(:mod:`console.live`) turns those into the same tables and events the batch
parsers produce and runs the same analysis core on them.

What kind of input a file is has one recogniser, :func:`parsers.kinds.classify_head`;
a followed file's lines are routed by it (:mod:`console.inputs.file_lines`).

A source is named by a URI (:func:`console.inputs.uri.open_source`)::

    file:PATH                      follow a growing file (tail -F): a diagnostic, GNSS, CAN or frame log
    -, file:-, a FIFO's path       a stream (standard input, a pipe), read as it comes until its writer closes it
    gpsd://HOST:PORT[/DEVICE]      a running gpsd, WATCH JSON
    mqtt://HOST:PORT/TOPIC         LoRaWAN uplinks (ChirpStack v4, The Things Stack v3)
    mqtts://HOST:PORT/TOPIC        the same over TLS
    can:INTERFACE[:CHANNEL]        a live CAN bus through python-can
"""
