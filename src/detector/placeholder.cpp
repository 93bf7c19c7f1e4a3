// placeholder until detector sources land
