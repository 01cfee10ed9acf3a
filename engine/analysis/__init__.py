"""Closed forms and signal analysis used to check and read runs: beam theory
(``beam_theory``) and spectra (``spectrum``)."""
