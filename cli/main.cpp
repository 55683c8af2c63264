#include <iostream>
int main() { std::cout << "isohex\n"; return 0; }
