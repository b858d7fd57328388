#include <lucent/lucent.h>
#include <stdio.h>
int main(void) { puts("lucent " LU_VERSION_STRING); return 0; }
