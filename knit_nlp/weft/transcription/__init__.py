"""The weft model as a nonlinear program: one factory (``factory.transcribe``) and one written
protocol (``protocol.WeftTranscription``) for what every transcription offers. ``full`` is the
NLP of eq. 13 over every loop (closed-form derivatives in ``derivatives``); ``condensed`` is
the reduced model of eqs. 22-27 (the map in ``reduction``) in the paper's variables; ``rows``
holds the material points and constraint rows both describe the same way."""
