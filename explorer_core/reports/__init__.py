"""Static figures (matplotlib, imported only here and only when a picture is asked for) of the analyses
and studies, for the command line and ``bilimovich reproduce``.
"""
