"""Pure learning pieces (Pegasos, graph cut, SVR, Baum-Welch) used by filters and measurers."""
