"""Studies built from the analyses: the work-precision benchmark (:mod:`.bench`), where the methods fail
(:mod:`.failures`) and the reproduction of the paper (:mod:`.reproduce`).
"""
