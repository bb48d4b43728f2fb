"""Reading the solution: von Mises peaks, features, section stresses, the hand formulas, the error bar."""
