"""The modes: thin drivers that feed the pipeline and choose its sinks."""
