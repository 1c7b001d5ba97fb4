"""Every compiled (Numba) kernel of prismbatch; private: the engine modules wrap them."""
