# loopcheck/reduced/kernels/partition.py is compiled with the other kernels; it declares nothing at C level
# (it cimports the output types it reads in its own source).
